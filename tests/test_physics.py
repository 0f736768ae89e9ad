"""mdroll.physics: one home per equation (each eq tag defined once in mdroll), and every closed
form against an independent number (physics.md's defaults, quadrature, hand arithmetic)."""

import ast
import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy import integrate, optimize

from mdroll import Params, physics, run_ensemble

PACKAGE = Path(physics.__file__).resolve().parent

E_STAR = 210e9 / (2 * (1 - 0.3**2))  # 1.153846e11 Pa
D0 = (3 * 40e3 / (4 * E_STAR * math.sqrt(0.5))) ** (2 / 3)
A = math.sqrt(D0 * 0.5)
Q_MIN = 2 * math.pi / 5e-3

#: The defining marker (physics.py's module docstring): a docstring whose first line starts
#: "Eq 40:", "Eq 1-2:", "Eq 56, 58:", "Eq 50 (continuum limit):" or "Section 4.2 (contact stiffness):".
DEFINES = re.compile(r"^(?:Eq (?P<eqs>\d+(?:\s*[-,]\s*\d+)*)|Section (?P<section>\d+(?:\.\d+)*))(?: \((?P<variant>[^)]*)\))?:")


def _tags(first_line: str) -> list[tuple[str, str]]:
    """The (relation, variant) keys a docstring's first line defines: one per eq number."""
    match = DEFINES.match(first_line)
    if not match:
        return []
    variant = match["variant"] or ""
    if match["section"]:
        return [(f"section {match['section']}", variant)]
    numbers = set()
    for part in re.split(r"\s*,\s*", match["eqs"]):
        lo, _, hi = part.partition("-")
        numbers.update(range(int(lo), int(hi or lo) + 1))
    return [(f"eq {n}", variant) for n in sorted(numbers)]


def _definitions() -> dict[tuple[str, str], list[str]]:
    """Every defining docstring in mdroll/: key -> ["module:function", ...]."""
    found: dict[tuple[str, str], list[str]] = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                doc = ast.get_docstring(node)
                if doc:
                    where = f"{path.relative_to(PACKAGE.parent)}:{node.name}"
                    for key in _tags(doc.strip().splitlines()[0]):
                        found.setdefault(key, []).append(where)
    return found


def test_the_marker_reads_tags():
    assert _tags("Eq 1-2: effective modulus") == [("eq 1", ""), ("eq 2", "")]
    assert _tags("Eq 56, 58: plateau") == [("eq 56", ""), ("eq 58", "")]
    assert _tags("Eq 50 (continuum limit): ...") == [("eq 50", "continuum limit")]
    assert _tags("Section 4.2 (contact stiffness): k_c") == [("section 4.2", "contact stiffness")]
    assert _tags("Eq 49 (N) for the wheel at spring c") == []  # a citation, not a definition
    assert _tags("Reference of eq 48: ...") == []
    assert _tags("Eq 38: window") == [("eq 38", "")]


def test_each_equation_is_defined_once():
    definitions = _definitions()
    twice = {f"{key[0]} {key[1]}".strip(): where for key, where in definitions.items() if len(where) > 1}
    assert not twice, f"defined in more than one place: {twice}"
    # variants of one equation (eq 50 and its continuum limit) live in one module
    modules: dict[str, set[str]] = {}
    for (relation, _), where in definitions.items():
        modules.setdefault(relation, set()).update(w.split(":")[0] for w in where)
    split = {relation: files for relation, files in modules.items() if len(files) > 1}
    assert not split, f"one equation defined in several modules: {split}"


def test_every_physics_function_defines_its_relation():
    functions = [name for name, value in vars(physics).items()
                 if callable(value) and not name.startswith("_") and getattr(value, "__module__", "") == physics.__name__]
    assert len(functions) >= 28
    untagged = [name for name in functions if not _tags(getattr(physics, name).__doc__.strip().splitlines()[0])]
    assert not untagged
    expected = {1, 2, 7, 14, 15, 21, 23, 26, 27, 28, 33, 38, 39, 40, 47, 48, 50, 56, 58, 60}
    defined_here = {int(key[0].split()[1]) for key, where in _definitions().items()
                    if key[0].startswith("eq") and any(w.startswith("mdroll/physics.py") for w in where)}
    assert expected <= defined_here


def test_physics_imports_numpy_only():
    tree = ast.parse(Path(physics.__file__).read_text())
    imported = {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
    imported |= {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
    assert imported <= {"__future__", "math", "numpy"}


# ---------------------------------------------------------------------------------- contact
def test_contact_at_the_thesis_defaults():
    assert physics.effective_modulus(210e9, 0.3) == pytest.approx(E_STAR, rel=1e-15)
    d0 = physics.hertz_indentation(40e3, E_STAR, 0.5)
    assert d0 == pytest.approx(D0, rel=1e-15)
    assert d0 == pytest.approx(51.32e-6, rel=1e-4)  # physics.md section 1
    a = physics.contact_radius(d0, 0.5)
    assert a == pytest.approx(5.066e-3, rel=1e-4)
    k_c = physics.contact_stiffness(E_STAR, a)
    assert physics.resonance_frequency(k_c, 500.0) == pytest.approx(1529, rel=1e-3)  # physics.md section 5
    assert physics.resonance_frequency(k_c, 500.0) == pytest.approx(math.sqrt(2 * a * E_STAR / 500), rel=1e-15)
    assert physics.spring_stiffness(E_STAR, 5e-6) == pytest.approx(E_STAR * 5e-6, rel=1e-15)
    # eq 7: the MDR profile is twice the paraboloid r^2 / (2R), so at the contact edge g(a) = d0 (eq 15)
    assert physics.indenter_profile(a, 0.5) == pytest.approx(d0, rel=1e-14)
    assert physics.indenter_profile(5e-6, 0.5) == pytest.approx(5e-11, rel=1e-15)
    assert physics.edge_coefficient(E_STAR, 0.5, a) == pytest.approx(E_STAR * 0.5 / (4 * A), rel=1e-14)
    # eq 47: raising the profile's edge by h moves the edge to where g = d0 + h, g the MDR profile
    h = 1e-9
    moved = float(__import__("scipy.optimize").optimize.brentq(lambda x: physics.indenter_profile(x, 0.5) - d0 - h, a, 2 * a,
                                                               xtol=1e-22, rtol=1e-15))
    assert physics.edge_displacement(h, 0.5, a) == pytest.approx(moved - a, rel=1e-5)


@pytest.mark.parametrize("F_N, R, E", [(40e3, 0.5, 210e9), (1e3, 0.1, 70e9), (2e5, 0.46, 200e9)])
def test_hertz_force_inverts_eq14_and_its_slope_is_k_c(F_N, R, E):
    E_star = physics.effective_modulus(E, 0.3)
    d0 = physics.hertz_indentation(F_N, E_star, R)
    assert physics.hertz_force(d0, E_star, R) == pytest.approx(F_N, rel=1e-12)
    step = 1e-6 * d0
    slope = (physics.hertz_force(d0 + step, E_star, R) - physics.hertz_force(d0 - step, E_star, R)) / (2 * step)
    assert slope == pytest.approx(physics.contact_stiffness(E_star, physics.contact_radius(d0, R)), rel=1e-8)


@pytest.mark.parametrize("omega_dt", [0.01, 0.5, 1.9])
def test_euler_phase_is_the_angle_of_the_step_matrix(omega_dt):
    omega, dt = 1529.0, omega_dt / 1529.0
    # semi-implicit Euler on y'' = -omega^2 y: v += -omega^2 y dt, then y += v dt
    step = np.array([[1 - (omega * dt) ** 2, dt], [-omega**2 * dt, 1.0]])
    eigenvalues = np.linalg.eigvals(step)
    assert np.abs(eigenvalues) == pytest.approx([1.0, 1.0], rel=1e-12)
    assert abs(np.angle(eigenvalues[0])) == pytest.approx(physics.euler_resonance_phase(omega, dt), rel=1e-12)


@pytest.mark.parametrize("q", [0.0, 3.0, 150.0, 620.0, 4000.0])
def test_window_transforms_against_quadrature(q):
    a = A
    window = integrate.quad(lambda x: math.cos(q * x), -a, a, limit=200)[0]
    assert physics.contact_window_transform(q, a) == pytest.approx(window, rel=1e-10, abs=1e-13 * a)
    cap = integrate.quad(lambda x: (a * a - x * x) * math.cos(q * x), -a, a, limit=200)[0]
    assert physics.contact_geometry_transform(q, a) == pytest.approx(cap, rel=1e-9, abs=1e-12 * a**3)
    assert physics.contact_window_transform(np.array([q]), a).shape == (1,)


def test_eq27_zeros_are_spaced_by_the_eq26_period():
    a = A
    zeros = [optimize.brentq(lambda q: float(physics.contact_geometry_transform(q, a)),
                             (n * math.pi + 0.01) / a, (n * math.pi + math.pi / 2 - 1e-9) / a) for n in (60, 61)]
    assert zeros[1] - zeros[0] == pytest.approx(physics.modulation_period(a), rel=1e-4)


def test_modulation_phase_is_eq39s_not_eq27s():
    """Eq 27's zeros (tan qa = qa, brentq) lie at q a / pi = 2.46, 3.47, 4.48; the minima of a
    periodic ensemble's force PSD (flattened by q^(2H+3), eq 23) at the integers 3..6, the zeros
    of sin^2(q a) in eq 39, within two bins, and at least 0.4 period from eq 27's."""
    a = A
    g_zeros = [optimize.brentq(lambda x: math.tan(x) - x, n * math.pi + 0.1, n * math.pi + math.pi / 2 - 1e-9) / math.pi
               for n in (2, 3, 4, 5, 6)]
    np.testing.assert_allclose(g_zeros[:3], [2.4590, 3.4709, 4.4774], atol=1e-4)
    p = Params(L=0.5)
    result = run_ensemble(p, realizations=8, boundary="periodic", window=False, device="cpu", progress=False)
    x = result.q * p.a / math.pi
    flat = result.force_psd * result.q ** (2 * p.H + 3)
    step = float(x[1] - x[0])
    for n in (3, 4, 5, 6):
        near = np.flatnonzero(np.abs(x - n) < 0.4)
        minimum = x[near[np.argmin(flat[near])]]
        assert abs(minimum - n) < 2 * step, (n, minimum)
        assert np.min(np.abs(minimum - np.array(g_zeros))) > 0.4


def test_forward_euler_growth_over_the_thesis_run():
    """Forward Euler on y'' = -omega^2 y multiplies the amplitude by sqrt(1 + (omega dt)^2) a step
    (the step matrix's eigenvalue, numpy): at the defaults' omega_0 dt over 1 036 800 steps that
    is exp(N (omega dt)^2 / 2) = 1.35 in amplitude and 1.83 in energy."""
    p = Params()
    w = p.omega_0 * p.dt
    step = np.array([[1.0, p.dt], [-p.omega_0**2 * p.dt, 1.0]])  # y += dt v, v += -omega^2 y dt, old values
    growth = float(np.abs(np.linalg.eigvals(step)[0])) ** 1_036_800
    assert growth == pytest.approx(math.exp(1_036_800 * w * w / 2), rel=1e-6)
    assert growth == pytest.approx(1.354, abs=0.002) and growth**2 == pytest.approx(1.833, abs=0.004)


# ---------------------------------------------------------------------------------- roughness
def test_band_psd_and_lambda_A_normalization():
    dq = 2 * math.pi / 0.5
    q = dq * np.arange(1, 50_001)  # 0.5 m at dx = 5 um
    q_max = math.pi / 5e-6
    # the grid wavenumber 2 pi k / L at q_min = 2 pi / 5 mm is inside however it rounds
    assert physics.in_roughness_band(dq * 100, Q_MIN, q_max)
    assert not physics.in_roughness_band([0.999 * Q_MIN, 1.001 * q_max], Q_MIN, q_max).any()
    band = q[physics.in_roughness_band(q, Q_MIN, q_max)]
    assert band.size == 50_001 - 100
    lam = physics.lambda_A_discrete(0.5e-6, 0.7, band, dq)
    C = physics.roughness_psd(np.concatenate([-q, q]), lam, 0.7, Q_MIN, q_max)
    assert dq * C.sum() == pytest.approx(0.25e-12, rel=1e-13)  # the two-sided PSD sums to h0^2
    assert physics.roughness_psd(2 * Q_MIN, lam, 0.7, Q_MIN, q_max) == pytest.approx(lam * (2 * Q_MIN) ** -2.4, rel=1e-15)
    assert physics.roughness_psd(0.5 * Q_MIN, lam, 0.7, Q_MIN, q_max) == 0.0


@pytest.mark.parametrize("H", [0.3, 0.7])
def test_lambda_A_discrete_tends_to_the_continuum(H):
    dq = 2 * math.pi / 50.0  # L = 50 m: q_min / dq = 10^4
    q_max = 100 * Q_MIN
    band = dq * np.arange(10_000, 1_000_001)
    discrete = physics.lambda_A_discrete(0.5e-6, H, band, dq)
    continuum = physics.lambda_A_continuum(0.5e-6, H, Q_MIN)
    assert continuum == pytest.approx(H * 0.25e-12 * Q_MIN ** (2 * H), rel=1e-15)
    # finite q_max: 2 int_{q_min}^{q_max} q^(-2H-1) dq = (q_min^(-2H) - q_max^(-2H)) / H
    assert discrete == pytest.approx(continuum / (1 - (Q_MIN / q_max) ** (2 * H)), rel=1e-4)


# ---------------------------------------------------------------------------------- spectra
def test_hann_window_by_hand():
    np.testing.assert_allclose(physics.hann_window(4), np.array([0.0, 0.5, 1.0, 0.5]) / math.sqrt(0.375), rtol=1e-15)
    assert np.mean(physics.hann_window(1000) ** 2) == pytest.approx(1.0, rel=1e-14)


def test_psd_convention_parseval_and_a_cosine():
    rng = np.random.default_rng(3)
    n, dx = 64, 5e-6
    x = rng.standard_normal(n)
    C = physics.psd_from_transform(np.fft.fft(x), n, dx)  # all k, both signs
    assert (2 * math.pi / (n * dx)) * C.sum() == pytest.approx(np.mean(x**2), rel=1e-13)
    cosine = 3.0 * np.cos(2 * math.pi * 5 * np.arange(n) / n)
    C = physics.psd_from_transform(np.fft.rfft(cosine), n, dx)
    assert C[5] == pytest.approx(n * dx / (2 * math.pi) * 1.5**2, rel=1e-13)


def test_eq39_and_eq40_by_hand():
    q = np.array([0.5 * Q_MIN, 2 * Q_MIN, 10 * Q_MIN])
    lam, q_max = 2.5e-12, math.pi / 5e-6
    expected = lam * (2 * E_STAR / q) ** 2 * q ** (-2.4) * np.sin(q * A) ** 2
    expected[0] = 0.0  # below q_min: no roughness, no linear force
    np.testing.assert_allclose(physics.force_psd_high_band(q, lam, 0.7, Q_MIN, q_max, E_STAR, A), expected, rtol=1e-12)
    # one point in plain numbers: q = 2 q_min = 2513.274 rad/m, q a = 12.73174, sin^2(q a) = 0.0270975
    point = 2.5e-12 * (2 * 1.153846e11 / 2513.274) ** 2 * 2513.274**-2.4 * 0.0270975
    assert expected[1] == pytest.approx(point, rel=1e-4)
    # eq 39 at q = 0: the whole contact moves with the mean height, (2 E* a)^2 C
    assert physics.force_psd_linear(0.0, 1.0, E_STAR, A) == pytest.approx((2 * E_STAR * A) ** 2, rel=1e-15)


def test_acceleration_transfer_by_hand():
    k_c, m = 1.17e9, 500.0
    omega = np.array([100.0, 3000.0])
    np.testing.assert_allclose(physics.acceleration_transfer(omega, k_c, m), omega**4 / (k_c - m * omega**2) ** 2, rtol=1e-15)
    assert physics.acceleration_transfer(math.sqrt(k_c / m), k_c, m) == np.inf


def test_thesis_scalars_by_hand():
    assert physics.transition_frequency(Q_MIN, 10.0) == pytest.approx(2 * math.pi / 5e-3 * 10, rel=1e-15)  # eq 21
    assert physics.power_law_exponent(0.7) == pytest.approx(-4.4)  # eq 23
    assert physics.modulation_period(A) == pytest.approx(math.pi / A, rel=1e-15)  # eq 26
    assert physics.h0_scaling(0.5e-6, 1e-6) == pytest.approx(4.0)  # eq 28
    args = (E_STAR, 0.5, 0.5e-6, 0.7, A, Q_MIN)
    limit = E_STAR**2 * 0.25 * (0.5e-6) ** 4 * 0.49 / (3.8 * A**2 * Q_MIN)
    assert physics.force_psd_low_band_limit(*args) == pytest.approx(limit, rel=1e-12)
    eq58 = 1.3 * E_STAR**2 * 0.25 * (0.5e-6) ** 4 * 0.977**2 / (A**2 * Q_MIN)
    assert physics.force_psd_plateau_thesis(*args) == pytest.approx(eq58, rel=1e-12)
    # the convention factor of physics.md section 7: eq 58 is ~10x the closed-form limit
    for hurst in (0.3, 0.7, 0.9):
        args = (E_STAR, 0.5, 0.5e-6, hurst, A, Q_MIN)
        assert 9.3 < physics.force_psd_plateau_thesis(*args) / physics.force_psd_low_band_limit(*args) < 10.7
    # eq 60 is eq 58 integrated over a band dq: 1.14^2 = 1.2996 ~ 1.3
    args = (E_STAR, 0.5, 0.5e-6, 0.7, A, Q_MIN)
    rms = physics.band_rms_force_thesis(*args, 100.0)
    assert rms**2 / (physics.force_psd_plateau_thesis(*args) * 100.0) == pytest.approx(1.14**2 / 1.3, rel=1e-12)


def _low_band(p, q):
    grid = p.dq * np.arange(p.n_points // 2 + 1)
    return physics.force_psd_low_band(q, p.psd(grid), p.dq, p.E_star, p.R, p.a)


def test_low_band_self_convolution_against_a_double_loop():
    p = Params(L=0.0256, dx=5e-4, q_min=2 * math.pi / 0.0064)  # 51 points, a/dx = 10
    dq = 2 * math.pi / p.length
    C = {int(j): float(p.psd(j * dq)) for j in range(-(p.n_points // 2), p.n_points // 2 + 1)}
    for k in range(0, 4):
        conv = sum(C[j] * C.get(k - j, 0.0) for j in C)
        expected = 4 * (E_STAR * p.R / (4 * p.a)) ** 2 * math.cos(k * dq * p.a) ** 2 * 2 * dq * conv
        assert _low_band(p, [k * dq])[0] == pytest.approx(expected, rel=1e-12)
    with pytest.raises(ValueError, match="grid"):
        _low_band(p, [0.5 * dq])


def test_low_band_tends_to_its_limit():
    p = Params(L=2.0, dx=20e-6)  # q_max = 125 q_min, 2 pi / L = 0.0025 q_min
    first = _low_band(p, [p.dq])[0]
    assert first == pytest.approx(physics.force_psd_low_band_limit(p.E_star, p.R, p.h0, p.H, p.a, p.q_min), rel=0.03)
