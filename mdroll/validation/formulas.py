"""Analytic formulas of the thesis, one function per equation (physics.md section 7).

PSDs follow the two-sided convention of physics.md section 3: ``C(q)`` in (unit^2 m) per rad/m,
``<x^2> = integral over all q of C(q) dq``; ``C(omega) = C(q) / v0``.
"""

from __future__ import annotations

import math

import numpy as np

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
