"""Every closed-form relation of the model, one function each (physics.md; thesis eq N).

This module is the bottom layer of mdroll: it imports numpy only, and takes plain floats and
arrays (never a :class:`mdroll.Params`), so that ``Params``' derived properties, the kernels'
launch constants, the validation, the plots, the studies and the inverse fit all call the same
function. Units are SI throughout: pascal, metre, kilogram, newton, second; wavenumbers q in
rad/m, angular frequencies omega in rad/s.

Spectral convention (physics.md sections 3 and 6): a series of N samples spaced dx over
L = N dx has the two-sided PSD ``C(q_k) = L / (2 pi) |B(q_k)|^2`` at ``q_k = 2 pi k / L`` with
``B(q_k) = (1/N) sum_s x_s exp(-i q_k s dx)``, so that ``<x^2> = sum_k (2 pi / L) C(q_k)`` over
k of both signs; ``C(omega) = C(q) / v0`` at ``omega = q v0``.

Convention for the docstrings here: the first line of the function that *defines* a relation
starts with its tag, ``Eq N:`` (thesis numbering; ``Eq N-M``, ``Eq N, M`` for several, and a
parenthesised variant such as ``Eq 50 (continuum limit):``) or ``Section S:`` for relations of
physics.md without a thesis number. tests/test_physics.py fails if two functions anywhere in
mdroll define the same tag. Elsewhere, cite relations in lower case ("eq 40").
"""

from __future__ import annotations

import math

import numpy as np

#: 2 pi, the one Python copy (Warp kernels derive their ``wp.constant`` from it).
TWO_PI = math.tau

#: ``1 / sqrt(3/8)``: the periodic Hann window ``0.5 - 0.5 cos(2 pi s / n)`` has mean square 3/8
#: (n >= 3); this factor scales it to 1 (:func:`hann_window`, and the kernels' windowed spectra).
HANN_NORM = math.sqrt(8.0 / 3.0)

#: The empirical Hurst offset of the thesis's low-band fits, eq 56, 58 and 60: ``(0.277 + H)``.
THESIS_HURST_OFFSET = 0.277

#: Relative tolerance of the roughness band's edges: a grid wavenumber that lands on a cutoff up
#: to rounding (e.g. q_k = 2 pi / 5 mm) counts as inside.
BAND_EDGE_TOLERANCE = 1e-12


# ---------------------------------------------------------------------------------- contact
def effective_modulus(E, nu):
    """Eq 1-2: effective modulus of two bodies of the same material, ``E* = E / (2 (1 - nu^2))``.

    Parameters: ``E`` Young's modulus (Pa), ``nu`` Poisson's ratio (dimensionless, in (-1, 0.5)).
    Returns E* (Pa).
    """
    return E / (2.0 * (1.0 - nu**2))


def hertz_indentation(F_N, E_star, R):
    """Eq 14: Hertz indentation of a rigid sphere on an elastic half-space under the load F_N,
    ``d0 = (3 F_N / (4 E* sqrt(R)))^(2/3)``.

    Parameters: ``F_N`` normal load (N), ``E_star`` effective modulus (Pa), ``R`` radius (m).
    Returns d0 (m).
    """
    return (3.0 * F_N / (4.0 * E_star * np.sqrt(R))) ** (2.0 / 3.0)


def contact_radius(d, R):
    """Eq 15: Hertz contact radius at indentation d, ``a = sqrt(d R)``.

    Parameters: ``d`` indentation (m), ``R`` radius (m). Returns a (m).
    """
    return np.sqrt(d * R)


def hertz_force(d, E_star, R):
    """Section 1 (Hertz force): normal force of the smooth contact at indentation d,
    ``F = (4/3) E* a^3 / R`` with ``a = sqrt(d R)`` (eq 15); the inverse of eq 14, so
    ``hertz_force(d0) = F_N``.

    Parameters: ``d`` indentation (m), ``E_star`` (Pa), ``R`` (m). Returns F (N).
    Written ``4 E* a^3 / (3 R)``, the order the edge kernel's device twin uses
    (:func:`mdroll.kernels.edge.edge_geometry`), so host and device agree to the last bit.
    """
    a = contact_radius(d, R)
    return 4.0 * E_star * a * a * a / (3.0 * R)


def indenter_profile(x, R):
    """Eq 7: the MDR-transformed profile of the paraboloid ``f(r) = r^2 / (2 R)``, ``g(x) = x^2 / R``
    (twice the original parabola, eq 5-7): spring x lies g(x) below the indenter's tip.

    Parameters: ``x`` distance from the wheel centre (m, any shape), ``R`` radius (m). Returns g (m).
    ``indenter_profile(dx, R) = dx^2 / R`` is the kernels' curvature in spring units: spring l
    is lowered by ``(dx^2 / R) (l - c)^2``.
    """
    return x * x / R


def spring_stiffness(E_star, dx):
    """Section 2 (spring stiffness): stiffness of one MDR spring, ``k = E* dx`` (eq 11-12).

    Parameters: ``E_star`` (Pa), ``dx`` spring spacing (m). Returns k (N/m).
    """
    return E_star * dx


def contact_stiffness(E_star, a):
    """Section 4.2 (contact stiffness): linearized Hertz stiffness ``k_c = dF/dd = 2 E* a``.

    Parameters: ``E_star`` (Pa), ``a`` contact radius (m). Returns k_c (N/m).
    """
    return 2.0 * E_star * a


def resonance_frequency(k_contact, m):
    """Section 4.2 (contact resonance): the wheel on its contact spring,
    ``omega_0 = sqrt(k_c / m) = sqrt(2 a E* / m)``.

    Parameters: ``k_contact`` k_c (N/m), ``m`` wheel mass (kg). Returns omega_0 (rad/s).
    """
    return np.sqrt(k_contact / m)


def euler_resonance_phase(omega_0, dt):
    """Section 5 (semi-implicit Euler resonance): phase advance per step of the semi-implicit
    Euler oscillator ``v += -omega_0^2 y dt; y += v dt``, ``phi = 2 asin(omega_0 dt / 2)``
    (its eigenvalues are ``exp(+-i phi)``; stable for ``omega_0 dt < 2``).

    Parameters: ``omega_0`` (rad/s), ``dt`` time step (s). Returns phi (rad per step).
    """
    return 2.0 * np.arcsin(0.5 * omega_0 * dt)


def edge_coefficient(E_star, R, a):
    """Eq 47-48: coefficient of the quadratic edge force, ``c = E* R / (4 a)``: each contact
    edge at height h adds ``c h^2`` to the force (eq 48-49).

    Parameters: ``E_star`` (Pa), ``R`` (m), ``a`` contact radius (m). Returns c (N/m^2).
    """
    return E_star * R / (4.0 * a)


def edge_displacement(h, R, a):
    """Eq 47 (edge displacement): how far a contact edge moves when the roughness under it rises by
    h, ``da = h / g'(a) = h R / (2 a)`` (the gap's slope at the edge g'(a) = 2 a / R; physics.md
    section 4, the derivation of eq 47-49).

    Parameters: ``h`` height (m), ``R`` wheel radius (m), ``a`` contact radius (m). Returns da (m).
    """
    return h * R / (2.0 * a)


def contact_window_transform(q, a):
    """Eq 38: Fourier transform of the contact window, the indicator of [-a, a],
    ``W(q) = integral_{-a}^{a} exp(-i q x) dx = 2 sin(q a) / q`` (``2 a`` at q = 0).

    The MDR contact filters the line linearly through it: a roughness mode of amplitude B(q)
    adds a force ``E* W(q) B(q)`` (eq 38), hence eq 39-40.
    Parameters: ``q`` wavenumber (rad/m, any shape), ``a`` (m). Returns W (m).
    """
    q = np.asarray(q, dtype=np.float64)
    return 2.0 * a * np.sinc(q * a / np.pi)


def contact_geometry_transform(q, a):
    """Eq 27: Fourier transform of the thesis's contact-geometry function ``g(x) = a^2 - x^2`` on
    ``|x| < a`` (0 outside), ``G(q) = 4 (sin(q a) - q a cos(q a)) / q^3`` (``4 a^3 / 3`` at q = 0).

    Its zeros (``tan(q a) = q a``) become spaced by pi / a at large q a: the thesis's explanation
    of the modulation period of eq 26.
    Parameters: ``q`` (rad/m, any shape), ``a`` (m). Returns G (m^3).
    """
    q = np.asarray(q, dtype=np.float64)
    qa = q * a
    small = np.abs(qa) < 1e-3
    safe = np.where(small, 1.0, q)
    exact = 4.0 * (np.sin(qa) - qa * np.cos(qa)) / safe**3
    # series 4 a^3 (1/3 - (qa)^2/30 + ...): the closed form cancels to nothing near 0
    series = 4.0 * a**3 * (1.0 / 3.0 - qa**2 / 30.0)
    return np.where(small, series, exact)


# ---------------------------------------------------------------------------------- roughness
def in_roughness_band(q, q_min, q_max):
    """Section 3 (roughness band): mask of ``q_min <= |q| <= q_max``, inclusive to a relative
    :data:`BAND_EDGE_TOLERANCE` at both cutoffs.

    Parameters: ``q`` (rad/m, any shape), ``q_min``, ``q_max`` (rad/m). Returns a bool array.
    """
    q = np.abs(np.asarray(q, dtype=np.float64))
    return (q >= q_min * (1.0 - BAND_EDGE_TOLERANCE)) & (q <= q_max * (1.0 + BAND_EDGE_TOLERANCE))


def roughness_psd(q, lambda_A, H, q_min, q_max):
    """Eq 33: two-sided PSD of the 1D MDR line, ``C_1D(q) = lambda A |q|^(-2H-1)`` for
    ``q_min <= |q| <= q_max`` (:func:`in_roughness_band`), else 0.

    Parameters: ``q`` (rad/m, any shape), ``lambda_A`` prefactor (m^(2-2H), eq 50), ``H`` Hurst
    exponent, ``q_min``, ``q_max`` (rad/m). Returns C_1D (m^3).
    """
    q = np.abs(np.asarray(q, dtype=np.float64))
    inside = in_roughness_band(q, q_min, q_max)
    out = np.zeros_like(q)
    out[inside] = lambda_A * q[inside] ** (-2.0 * H - 1.0)
    return out


def lambda_A_discrete(h0, H, band_q, dq):
    """Eq 50: PSD prefactor lambda(H) A that gives the line the mean square height h0^2 on its
    grid (physics.md section 3): ``lambda A = h0^2 / (2 dq sum_k q_k^(-2H-1))`` over the band's
    positive grid wavenumbers q_k (the factor 2 counts -q_k).

    Parameters: ``h0`` RMS height (m), ``H`` Hurst exponent, ``band_q`` the wavenumbers
    ``q_k = k dq`` with q_min <= q_k <= q_max (rad/m), ``dq = 2 pi / L`` (rad/m).
    Returns lambda A (m^(2-2H)).
    """
    band_q = np.asarray(band_q, dtype=np.float64)
    return h0**2 / (2.0 * dq * float(np.sum(band_q ** (-2.0 * H - 1.0))))


def lambda_A_continuum(h0, H, q_min):
    """Eq 50 (continuum limit): ``lambda A = H h0^2 q_min^(2H)``, the limit of
    :func:`lambda_A_discrete` for L -> infinity and q_max -> infinity
    (``2 integral_{q_min}^inf q^(-2H-1) dq = q_min^(-2H) / H``).

    Parameters: ``h0`` (m), ``H``, ``q_min`` (rad/m). Returns lambda A (m^(2-2H)).
    """
    return H * h0**2 * q_min ** (2.0 * H)


# ---------------------------------------------------------------------------------- spectra
def hann_window(n, xp=np):
    """Section 6 (Hann window): ``w_s = (0.5 - 0.5 cos(2 pi s / n)) HANN_NORM``, s = 0..n-1, the
    periodic Hann window scaled by :data:`HANN_NORM` to ``mean(w^2) = 1`` (exactly so for n >= 3),
    which keeps a series' total power.

    Parameters: ``n`` samples; ``xp`` the array module (numpy, or cupy on CUDA).
    Returns w (dimensionless, shape (n,)).
    """
    return (0.5 - 0.5 * xp.cos(TWO_PI * xp.arange(n) / n)) * HANN_NORM


def psd_from_transform(transform, n, dx):
    """Section 6 (PSD convention): ``C(q_k) = L / (2 pi) |B(q_k)|^2`` with ``B = X / n``,
    ``L = n dx``, from the unnormalized DFT ``X_k = sum_s x_s exp(-2 pi i k s / n)`` of a
    series of n samples spaced dx.

    Parameters: ``transform`` X (unit, any array module), ``n`` samples, ``dx`` spacing (m).
    Returns C (unit^2 m), in the array module of ``transform``.
    """
    return (n * dx / TWO_PI) * (abs(transform) / n) ** 2


def force_psd_linear(q, line_psd, E_star, a):
    """Eq 39: force PSD of the linear MDR response to a line of any spectrum,
    ``C_F(q) = (E* W(q))^2 C_1D(q) = (2 E* / q)^2 sin^2(q a) C_1D(q)``, W from
    :func:`contact_window_transform` (``= k_c^2 sinc^2(q a) C_1D`` with k_c = 2 E* a).

    Parameters: ``q`` (rad/m), ``line_psd`` C_1D at q (m^3), ``E_star`` (Pa), ``a`` (m).
    Returns C_F (N^2 m).
    """
    return (E_star * contact_window_transform(q, a)) ** 2 * np.asarray(line_psd, dtype=np.float64)


def force_psd_high_band(q, lambda_A, H, q_min, q_max, E_star, a):
    """Eq 40: force PSD of the high band, eq 39 with the power law of eq 33,
    ``C_F(q) = lambda A (2 E* / q)^2 |q|^(-2H-1) sin^2(q a)`` for q_min <= |q| <= q_max, else 0.

    Parameters: ``q`` (rad/m), ``lambda_A`` (m^(2-2H), eq 50), ``H``, ``q_min``, ``q_max``
    (rad/m), ``E_star`` (Pa), ``a`` (m). Returns C_F (N^2 m).
    """
    return force_psd_linear(q, roughness_psd(q, lambda_A, H, q_min, q_max), E_star, a)


def acceleration_transfer(omega, k_contact, m):
    """Section 5.1 (decoupled response): the wheel of mass m on the linearized contact spring,
    ``m y'' = -F(t) - k_c y``: acceleration per unit force fluctuation,
    ``|A(omega) / F(omega)|^2 = omega^4 / (k_c - m omega^2)^2`` (infinite at omega_0).

    Parameters: ``omega`` (rad/s), ``k_contact`` k_c (N/m), ``m`` (kg). Returns ((m/s^2)/N)^2.
    """
    omega = np.asarray(omega, dtype=np.float64)
    with np.errstate(divide="ignore"):
        return omega**4 / (k_contact - m * omega**2) ** 2


def force_psd_low_band(q, line_psd, dq, E_star, R, a):
    """Section 7 (low band): closed-form force PSD below q_min, where the quadratic edge force of
    eq 48 is the whole fluctuation (derived for this project):

        C_F(q) = 4 c^2 cos^2(q a) C_{h^2}(q),   c = E* R / (4 a)  (eq 47-48),
        C_{h^2}(q_k) = 2 dq sum_j C_1D(q_j) C_1D(q_k - q_j)

    the discrete self-convolution of the line's PSD on its grid q_j = j dq, h^2 treated as
    Gaussian (Isserlis' factor 2).

    Parameters: ``q`` (rad/m) on the grid ``k dq``; ``line_psd`` C_1D(j dq) for j = 0..J (m^3;
    C_1D is even, and zero beyond J dq); ``dq = 2 pi / L`` (rad/m); ``E_star`` (Pa); ``R``, ``a``
    (m). Returns C_F (N^2 m). Raises ValueError if a q is off the grid.
    """
    q = np.abs(np.asarray(q, dtype=np.float64))
    k = np.rint(q / dq).astype(np.int64)
    if not np.allclose(k * dq, q, rtol=1e-9, atol=1e-9 * dq):
        raise ValueError("q must lie on the line's grid 2 pi k / L (rad/m)")
    half = np.asarray(line_psd, dtype=np.float64)
    two_sided = np.concatenate([half[:0:-1], half])  # C_1D(j dq), j = -J..J
    size = two_sided.size
    self_convolution = np.array([np.dot(two_sided[kk:], two_sided[: size - kk]) for kk in k.ravel()])
    c_h2 = 2.0 * dq * self_convolution.reshape(k.shape)
    c = edge_coefficient(E_star, R, a)
    return 4.0 * c * c * np.cos(q * a) ** 2 * c_h2


def force_psd_low_band_limit(E_star, R, h0, H, a, q_min):
    """Section 7 (low band, q -> 0): the limit of :func:`force_psd_low_band` for q_max -> infinity,
    ``C_F(0) = E*^2 R^2 h0^4 H^2 / ((4 H + 1) a^2 q_min)``.

    Parameters: ``E_star`` (Pa), ``R`` (m), ``h0`` (m), ``H``, ``a`` (m), ``q_min`` (rad/m).
    Returns C_F(0) (N^2 m).
    """
    return E_star**2 * R**2 * h0**4 * H**2 / ((4.0 * H + 1.0) * a**2 * q_min)


def force_psd_plateau_thesis(E_star, R, h0, H, a, q_min):
    """Eq 56, 58: the thesis's empirical low-band plateau, independent of L,
    ``C_F0 = 1.3 E*^2 R^2 h0^4 (0.277 + H)^2 / (a^2 q_min)`` (0.277: :data:`THESIS_HURST_OFFSET`).

    In the thesis's own spectral normalization, about 10x physics.md's (section 7): a factor to
    measure. Parameters as :func:`force_psd_low_band_limit`. Returns C_F0 (N^2 m).
    """
    return 1.3 * E_star**2 * R**2 * h0**4 * (THESIS_HURST_OFFSET + H) ** 2 / (a**2 * q_min)


def band_rms_force_thesis(E_star, R, h0, H, a, q_min, dq):
    """Eq 60: RMS force in a low band of width dq (thesis normalization, like eq 58),
    ``F_rms = 1.14 E* R h0^2 (0.277 + H) / a * sqrt(dq / q_min)``.

    Parameters as :func:`force_psd_low_band_limit`, and ``dq`` band width (rad/m). Returns N.
    """
    return 1.14 * E_star * R * h0**2 * (THESIS_HURST_OFFSET + H) / a * np.sqrt(dq / q_min)


def transition_frequency(q_min, v0):
    """Eq 21: the high-frequency band starts at ``omega_t = q_min v0``.

    Parameters: ``q_min`` (rad/m), ``v0`` rolling speed (m/s). Returns omega_t (rad/s).
    """
    return q_min * v0


def power_law_exponent(H):
    """Eq 23: the high band of the force and acceleration PSDs falls as ``q^-(2H+3)``.

    Parameter: ``H`` Hurst exponent. Returns the exponent ``-(2H + 3)`` (dimensionless).
    """
    return -(2.0 * H + 3.0)


def modulation_period(a):
    """Eq 26: period of the sin^2(q a) modulation of the high band, ``d_q = pi / a``
    (``d_omega = v0 d_q``).

    Parameter: ``a`` contact radius (m). Returns d_q (rad/m).
    """
    return math.pi / a


def h0_scaling(h0_from, h0_to):
    """Eq 28: the high band of the force and acceleration PSDs scales with h0^2: the factor
    ``(h0_to / h0_from)^2`` that carries a spectrum from one RMS height to another.

    Parameters: ``h0_from``, ``h0_to`` RMS heights (m). Returns the factor (dimensionless).
    """
    return (h0_to / h0_from) ** 2
