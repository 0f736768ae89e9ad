"""The analytic formulas of mdroll.validation.formulas against hand-computed values (physics.md section 7)."""

import math

import numpy as np
import pytest
from reference import rough_line

from mdroll import Params, contact_force
from mdroll.validation import formulas as f

P = Params()
E_STAR = 210e9 / (2 * (1 - 0.3**2))  # 1.153846e11 Pa
D0 = (3 * 40e3 / (4 * E_STAR * math.sqrt(0.5))) ** (2 / 3)
A = math.sqrt(D0 * 0.5)


def test_scalar_formulas_by_hand():
    assert A == pytest.approx(5.066e-3, rel=1e-3)
    assert f.resonance_frequency(P) == pytest.approx(math.sqrt(2 * A * E_STAR / 500), rel=1e-12)
    assert f.resonance_frequency(P) == pytest.approx(1529, rel=1e-3)  # physics.md section 5
    assert f.transition_frequency(P) == pytest.approx(2 * math.pi / 5e-3 * 10, rel=1e-12)  # eq 21
    assert f.power_law_exponent(P) == pytest.approx(-4.4)  # eq 23
    assert f.modulation_period(P) == pytest.approx(math.pi / A, rel=1e-12)  # eq 26
    assert f.h0_scaling(0.5e-6, 1e-6) == pytest.approx(4.0)  # eq 28
    q_min = 2 * math.pi / 5e-3
    limit = E_STAR**2 * 0.25 * (0.5e-6) ** 4 * 0.49 / (3.8 * A**2 * q_min)
    assert f.force_psd_low_band_limit(P) == pytest.approx(limit, rel=1e-12)
    eq58 = 1.3 * E_STAR**2 * 0.25 * (0.5e-6) ** 4 * (0.977) ** 2 / (A**2 * q_min)
    assert f.force_psd_plateau_thesis(P) == pytest.approx(eq58, rel=1e-12)
    # the convention factor of physics.md section 7: eq 58 is ~10x the closed-form limit
    assert f.force_psd_plateau_thesis(P) / limit == pytest.approx(1.3 * 0.977**2 * 3.8 / 0.49, rel=1e-12)
    for hurst, low, high in [(0.3, 9.3, 10.7), (0.9, 9.3, 10.7)]:
        p = P.replace(H=hurst)
        assert low < f.force_psd_plateau_thesis(p) / f.force_psd_low_band_limit(p) < high
    # eq 60 is eq 58 integrated over a band dq: 1.14^2 = 1.2996 ~ 1.3
    dq = 100.0
    assert f.band_rms_force_thesis(P, dq) ** 2 / (f.force_psd_plateau_thesis(P) * dq) == pytest.approx(1.14**2 / 1.3, rel=1e-12)


def test_eq40_by_hand():
    q = np.array([0.5 * P.q_min, 2 * P.q_min, 10 * P.q_min])
    expected = P.lambda_A * (2 * E_STAR / q) ** 2 * q ** (-2.4) * np.sin(q * A) ** 2
    expected[0] = 0.0  # below q_min: no roughness, no linear force
    np.testing.assert_allclose(f.force_psd_high_band(P, q), expected, rtol=1e-12)


def test_eq48_on_a_sinusoid():
    p = Params(L=0.1, dx=20e-6)
    x = np.arange(p.n_points) * p.dx
    k = 2 * np.pi * 3 / p.length  # a long wave
    h = 1e-6 * np.cos(k * x)
    c = E_STAR * 0.5 / (4 * p.a)
    expected = c * (1e-12 * np.cos(k * (x + p.a)) ** 2 + 1e-12 * np.cos(k * (x - p.a)) ** 2)
    # linear interpolation is off by at most (k dx)^2 / 8 of the amplitude (2x that on h^2)
    np.testing.assert_allclose(f.edge_quadratic_force(p, h), expected, rtol=(k * p.dx) ** 2 / 4)


def test_eq49_reference_equals_edge_kernel_and_hertz_on_a_smooth_line():
    p = Params(L=0.05, dx=10e-6)
    assert f.edge_force(p, np.zeros(p.n_points)) == pytest.approx(np.full(p.n_points, p.F_N), rel=1e-13)
    lines = np.stack([rough_line(p, 4, r) for r in range(2)])
    kernel = contact_force(lines, p, "edge", "periodic")
    np.testing.assert_allclose(f.edge_force(p, lines), kernel, rtol=1e-13, atol=1e-9)


def test_low_band_self_convolution_against_a_double_loop():
    p = Params(L=0.0256, dx=5e-4, q_min=2 * math.pi / 0.0064)  # 51 points, a/dx = 10
    dq = 2 * math.pi / p.length
    modes = np.arange(-(p.n_points // 2), p.n_points // 2 + 1)
    C = {int(j): float(p.psd(j * dq)) for j in modes}
    for k in range(0, 4):
        conv = sum(C[j] * C.get(k - j, 0.0) for j in C)
        expected = 4 * (E_STAR * p.R / (4 * p.a)) ** 2 * math.cos(k * dq * p.a) ** 2 * 2 * dq * conv
        assert f.force_psd_low_band(p, [k * dq])[0] == pytest.approx(expected, rel=1e-12)
    with pytest.raises(ValueError, match="grid"):
        f.force_psd_low_band(p, [0.5 * dq])


def test_low_band_tends_to_its_limit():
    p = Params(L=2.0, dx=20e-6)  # q_max = 125 q_min, 2 pi / L = 0.0025 q_min
    first = f.force_psd_low_band(p, [2 * math.pi / p.length])[0]
    assert first == pytest.approx(f.force_psd_low_band_limit(p), rel=0.03)
