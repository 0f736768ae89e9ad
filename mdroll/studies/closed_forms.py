"""The closed forms the studies compare with, bound to a :class:`mdroll.Params` (the one place the
studies call :mod:`mdroll.physics`); the band averages they are measured on are in
:mod:`.band_averages`."""

from __future__ import annotations

import numpy as np

from .. import physics
from ..params import Params


def high_band(p: Params, q) -> np.ndarray:
    """Force PSD (N^2 m) of the linear contact at wavenumbers ``q`` (rad/m): eq 40 for ``p``."""
    return physics.force_psd_high_band(q, p.lambda_A, p.H, p.q_min, p.q_max, p.E_star, p.a)


def transfer(p: Params, omega) -> np.ndarray:
    """|A/F|^2 ((m/s^2/N)^2) of the wheel on the linearized contact spring at ``omega`` (rad/s), section 5.1."""
    return physics.acceleration_transfer(omega, p.k_contact, p.m)


def line_psd(p: Params) -> np.ndarray:
    """C_1D(j dq) (m^3, eq 33) for j = 0..n/2 on the line's grid."""
    return p.psd(p.dq * np.arange(p.n_points // 2 + 1))


def low_band(p: Params, q, psd_of_line: np.ndarray | None = None) -> np.ndarray:
    """The closed-form low band (physics.md section 7): force PSD (N^2 m) below q_min at grid
    wavenumbers ``q`` (rad/m) of a periodic run."""
    psd_of_line = line_psd(p) if psd_of_line is None else psd_of_line
    return physics.force_psd_low_band(q, psd_of_line, p.dq, p.E_star, p.R, p.a)


def plateau_thesis(p: Params) -> float:
    """The thesis's plateau C_F0 (N^2 m, its own normalization): eq 56/58 for ``p``."""
    return physics.force_psd_plateau_thesis(p.E_star, p.R, p.h0, p.H, p.a, p.q_min)


def band_rms_thesis(p: Params, dq: float) -> float:
    """The thesis's RMS force (N) in a low band of width ``dq`` (rad/m): eq 60 for ``p``."""
    return physics.band_rms_force_thesis(p.E_star, p.R, p.h0, p.H, p.a, p.q_min, dq)
