"""Analytic formulas of the thesis, one function per equation (physics.md section 7).

PSDs follow the two-sided convention of physics.md section 3: ``C(q)`` in (unit^2 m) per rad/m,
``<x^2> = integral over all q of C(q) dq``; ``C(omega) = C(q) / v0``.
"""

from __future__ import annotations

import math

import numpy as np

from ..ensemble.spectra import array_module
from ..params import Params


def resonance_frequency(params: Params) -> float:
    """Contact resonance ``omega_0 = sqrt(2 a E* / m)`` (rad/s), section 4.2."""
    return math.sqrt(2.0 * params.a * params.E_star / params.m)


def transition_frequency(params: Params) -> float:
    """Eq 21: the high-frequency band starts at ``omega_t = q_min v0`` (rad/s)."""
    return params.q_min * params.v0


def power_law_exponent(params: Params) -> float:
    """Eq 23: the high band of the force PSD falls as ``q^-(2H+3)``; returns ``-(2H + 3)``."""
    return -(2.0 * params.H + 3.0)


def modulation_period(params: Params) -> float:
    """Eq 26: period of the sin^2(q a) modulation, ``d_q = pi / a`` (rad/m); ``d_omega = v0 d_q``."""
    return math.pi / params.a


def force_psd_high_band(params: Params, q) -> np.ndarray:
    """Eq 40: ``C_F(q) = lambda A (2 E* / q)^2 |q|^(-2H-1) sin^2(q a)`` (N^2 m) for q_min <= q <= q_max.

    ``q`` in rad/m; zero outside the roughness band. lambda A from :attr:`Params.lambda_A` (eq 50).
    """
    q = np.abs(np.asarray(q, dtype=np.float64))
    out = np.zeros_like(q)
    inside = params.in_band(q)
    qi = q[inside]
    out[inside] = params.lambda_A * (2.0 * params.E_star / qi) ** 2 * qi ** (-2.0 * params.H - 1.0) * np.sin(qi * params.a) ** 2
    return out


def acceleration_transfer(params: Params, omega) -> np.ndarray:
    """``|A(omega) / F(omega)|^2 = omega^4 / (k_c - m omega^2)^2`` ((m/s^2/N)^2): the wheel on the
    linearized contact spring (section 5.1), acceleration per unit force fluctuation."""
    omega = np.asarray(omega, dtype=np.float64)
    with np.errstate(divide="ignore"):
        return omega**4 / (params.k_contact - params.m * omega**2) ** 2


def h0_scaling(h0_from: float, h0_to: float) -> float:
    """Eq 28: the high band of the force and acceleration PSDs scales with h0^2; the factor
    ``(h0_to / h0_from)^2`` (dimensionless) that carries a spectrum from one RMS height to another."""
    return (h0_to / h0_from) ** 2


def _heights_at(lines, offset: float, dx: float):
    """h at x_s + offset for every spring s of each periodic line (R, n), by linear interpolation
    between springs (indices wrap); returns the shifted rows (m) in the array module of ``lines``."""
    xp = array_module(lines)
    whole = math.floor(offset / dx)
    frac = offset / dx - whole
    here = xp.roll(lines, -whole, axis=-1)
    return here + frac * (xp.roll(here, -1, axis=-1) - here)


def edge_quadratic_force(params: Params, lines, d: float | None = None):
    """Eq 48: the quadratic edge force ``E* R / (4 a) (h(x_w + a)^2 + h(x_w - a)^2)`` (N).

    ``lines`` (R, n) or (n,) heights h_i (m) on ``x_i = i dx`` (NumPy or CuPy), read as periodic;
    the wheel sits on every spring, ``x_w = s dx``, s = 0..n-1, and h between springs is the
    linear interpolant. ``a = sqrt(d R)`` with d = d0 (eq 14-15) unless given. Below q_min this
    is the whole force fluctuation up to constants (physics.md section 7).
    """
    a = math.sqrt((params.d0 if d is None else d) * params.R)
    right = _heights_at(lines, a, params.dx)
    left = _heights_at(lines, -a, params.dx)
    return params.E_star * params.R / (4.0 * a) * (right * right + left * left)


def edge_force(params: Params, lines, d: float | None = None):
    """Eq 49: ``F = F_Hertz(d) + E* integral_{x_w-a}^{x_w+a} h dx + E* R/(4a) (h(x_w+a)^2 + h(x_w-a)^2)`` (N).

    Same inputs and wheel positions as :func:`edge_quadratic_force`; ``F_Hertz(d) = (4/3) E* a^3 / R``
    and the integral is exact over the linear interpolant of h (the trapezoid rule on whole cells
    and the two fractional end cells): an independent array-code reference for the edge kernel.
    """
    xp = array_module(lines)
    d = params.d0 if d is None else d
    a = math.sqrt(d * params.R)
    dx = params.dx
    whole = math.floor(a / dx)
    # trapezoid rule over springs s - whole .. s + whole from a running sum of the wrapped line
    wrapped = xp.concatenate([lines[..., -whole:], lines, lines[..., : whole + 1]], axis=-1)
    running = xp.cumsum(wrapped, axis=-1)
    n = lines.shape[-1]
    window_sum = running[..., 2 * whole: 2 * whole + n] - xp.concatenate(
        [xp.zeros_like(running[..., :1]), running[..., : n - 1]], axis=-1)
    right_0, left_0 = xp.roll(lines, -whole, axis=-1), xp.roll(lines, whole, axis=-1)
    middle = window_sum - 0.5 * (right_0 + left_0)
    right_1 = _heights_at(lines, a, dx)
    left_1 = _heights_at(lines, -a, dx)
    partial = a / dx - whole
    ends = 0.5 * partial * ((right_0 + right_1) + (left_0 + left_1))
    integral = dx * (middle + ends)
    hertz = 4.0 / 3.0 * params.E_star * a**3 / params.R
    return hertz + params.E_star * integral + params.E_star * params.R / (4.0 * a) * (right_1**2 + left_1**2)


def force_psd_low_band(params: Params, q) -> np.ndarray:
    """Closed-form low band of the force PSD (physics.md section 7; derived for this project):

        C_F(q) = 4 c^2 cos^2(q a) C_{h^2}(q),   c = E* R / (4 a),
        C_{h^2}(q_k) = 2 (2 pi / L) sum_j C_1D(q_j) C_1D(q_k - q_j)

    (N^2 m), the discrete self-convolution of the line's PSD (eq 33 with lambda A of eq 50) on
    its grid q_j = 2 pi j / L. ``q`` (rad/m) must lie on that grid; valid below q_min, where eq
    48 is the whole fluctuation and h^2 is treated as Gaussian (Isserlis' factor 2).
    """
    q = np.abs(np.asarray(q, dtype=np.float64))
    dq = 2.0 * math.pi / params.length
    k = np.rint(q / dq).astype(np.int64)
    if not np.allclose(k * dq, q, rtol=1e-9, atol=1e-9 * dq):
        raise ValueError("q must lie on the line's grid 2 pi k / L (rad/m)")
    modes = np.arange(-(params.n_points // 2), params.n_points // 2 + 1)
    c1d = params.psd(modes * dq)
    self_convolution = np.array([np.dot(c1d[kk:], c1d[: c1d.size - kk]) for kk in k.ravel()])
    c_h2 = 2.0 * dq * self_convolution.reshape(k.shape)
    c = params.E_star * params.R / (4.0 * params.a)
    return 4.0 * c * c * np.cos(q * params.a) ** 2 * c_h2


def force_psd_low_band_limit(params: Params) -> float:
    """q -> 0 limit of :func:`force_psd_low_band` for q_max -> infinity (physics.md section 7):
    ``C_F(0) = E*^2 R^2 h0^4 H^2 / ((4 H + 1) a^2 q_min)`` (N^2 m)."""
    p = params
    return p.E_star**2 * p.R**2 * p.h0**4 * p.H**2 / ((4.0 * p.H + 1.0) * p.a**2 * p.q_min)


def force_psd_plateau_thesis(params: Params) -> float:
    """Eq 56/58, the thesis's empirical low-band plateau, independent of L:
    ``C_F0 = 1.3 E*^2 R^2 h0^4 (0.277 + H)^2 / (a^2 q_min)`` (N^2 m, in the thesis's own spectral
    normalization, about 10x the value of physics.md's convention: a factor to measure)."""
    p = params
    return 1.3 * p.E_star**2 * p.R**2 * p.h0**4 * (0.277 + p.H) ** 2 / (p.a**2 * p.q_min)


def band_rms_force_thesis(params: Params, dq: float) -> float:
    """Eq 60: RMS force (N) in a low band of width ``dq`` (rad/m):
    ``1.14 E* R h0^2 (0.277 + H) / a * sqrt(dq / q_min)`` (thesis normalization, like eq 58)."""
    p = params
    return 1.14 * p.E_star * p.R * p.h0**2 * (0.277 + p.H) / p.a * math.sqrt(dq / p.q_min)
