"""The array-code reference solutions of mdroll.validation.references against closed forms and the
edge kernel (eq 48-49)."""

import math

import numpy as np
import pytest
from reference import rough_line

from mdroll import Params, contact_force
from mdroll.validation.references import edge_force, edge_quadratic_force, heights_at

E_STAR = 210e9 / (2 * (1 - 0.3**2))  # 1.153846e11 Pa


def test_heights_at_interpolates_and_wraps():
    h = np.array([0.0, 1.0, 4.0, 9.0])
    np.testing.assert_allclose(heights_at(h, 0.25, 1.0), [0.25, 1.75, 5.25, 6.75], rtol=1e-15)
    np.testing.assert_allclose(heights_at(h, -1.0, 1.0), [9.0, 0.0, 1.0, 4.0], rtol=1e-15)


def test_eq48_on_a_sinusoid():
    p = Params(L=0.1, dx=20e-6)
    x = np.arange(p.n_points) * p.dx
    k = 2 * np.pi * 3 / p.length  # a long wave
    h = 1e-6 * np.cos(k * x)
    c = E_STAR * 0.5 / (4 * p.a)
    expected = c * (1e-12 * np.cos(k * (x + p.a)) ** 2 + 1e-12 * np.cos(k * (x - p.a)) ** 2)
    # linear interpolation is off by at most (k dx)^2 / 8 of the amplitude (2x that on h^2)
    np.testing.assert_allclose(edge_quadratic_force(p, h), expected, rtol=(k * p.dx) ** 2 / 4)


def test_eq49_reference_equals_edge_kernel_and_hertz_on_a_smooth_line():
    p = Params(L=0.05, dx=10e-6)
    assert edge_force(p, np.zeros(p.n_points)) == pytest.approx(np.full(p.n_points, p.F_N), rel=1e-13)
    lines = np.stack([rough_line(p, 4, r) for r in range(2)])
    kernel = contact_force(lines, p, "edge", "periodic")
    np.testing.assert_allclose(edge_force(p, lines), kernel, rtol=1e-13, atol=1e-9)
    # at another indentation the smooth line carries the Hertz force of that indentation
    d = 0.9 * p.d0
    a = math.sqrt(d * p.R)
    assert edge_force(p, np.zeros(p.n_points), d) == pytest.approx(np.full(p.n_points, 4 / 3 * E_STAR * a**3 / p.R), rel=1e-13)
