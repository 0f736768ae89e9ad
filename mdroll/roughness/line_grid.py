"""The spectrum a run's parameters name, and its values on the line's grid q_k = k 2 pi / L:
the generated lines' C_1D, their RMS, eq 39's linear force and the generator's mode amplitudes."""

from __future__ import annotations

import math

import numpy as np

from .. import physics
from ..errors import ParameterError
from ..params import Params
from .analytic import BandLimited, PowerLaw, RollOff
from .kinds import RoughnessSpectrum
from .tabulated import BandLevels, Tabulated, iso3095


def from_description(description: dict) -> RoughnessSpectrum:
    """The spectrum a :meth:`RoughnessSpectrum.describe` dict names (inverse of describe); a
    callable spectrum cannot be rebuilt (ParameterError)."""
    d = dict(description)
    model = d.pop("model", None)
    if model == "powerlaw":
        return PowerLaw(d["H"], d["q_min"], d["q_max"], d["prefactor"], d["kind"])
    if model == "rolloff":
        return RollOff(d["H"], d["q_r"], d["q_max"], d["prefactor"], d["q_low"])
    if model == "table":
        return Tabulated(d["q"], d["C"], d["kind"], d["absolute"], d["source"])
    if model == "bands":
        return BandLevels(d["wavelength_mm"], d["level_db"], d["kind"], d["source"])
    if model == "band_limited":
        return BandLimited(from_description(d["of"]), d["q_lo"], d["q_hi"])
    raise ParameterError(f"roughness description of model {model!r} cannot be rebuilt (a callable is API only)")



def from_params(params: Params) -> RoughnessSpectrum:
    """The spectrum that the roughness fields of ``params`` name (their defaults: eq 33)."""
    kind = params.spectrum_kind
    if params.roughness == "powerlaw":
        spectrum = PowerLaw(params.H, params.q_min, params.q_max)
    elif params.roughness == "rolloff":
        spectrum = RollOff(params.H, params.q_min if params.q_r is None else params.q_r, params.q_max)
    elif params.roughness == "table":
        spectrum = Tabulated.from_file(params.roughness_table, kind=kind, absolute=params.level == "absolute")
    elif params.roughness == "bands":
        spectrum = BandLevels.from_file(params.roughness_table, kind=kind)
    else:
        spectrum = iso3095()
    return spectrum


def resolve_level(params: Params, spectrum: RoughnessSpectrum) -> str:
    """The normalization of lines from ``spectrum``: ``params.roughness_level`` when set, else
    ``"absolute"`` for a spectrum with a level of its own and ``"rms"`` (eq 50) for a shape."""
    if params.roughness_level is not None:
        return params.roughness_level
    return "absolute" if spectrum.absolute else "rms"


def grid_psd(params: Params, spectrum: RoughnessSpectrum) -> np.ndarray:
    """C_1D(q_k) of the generated MDR lines at q_k = k dq, k = 0..n/2 (m^3, two-sided; C(0) = 0:
    lines have zero mean), cut at q_max: the spectrum's MDR PSD, scaled for the ``"rms"`` level
    (:func:`resolve_level`) by ``h0^2 / (2 dq sum_{k >= 1} C_k)`` (eq 50 for any spectrum), as it
    is for ``"absolute"``."""
    level = resolve_level(params, spectrum)
    q = params.dq * np.arange(params.n_points // 2 + 1, dtype=np.float64)
    C = spectrum.grid_mdr_psd(q, params.dq)
    C[0] = 0.0
    C[q > params.q_max * (1.0 + physics.BAND_EDGE_TOLERANCE)] = 0.0
    total = 2.0 * params.dq * float(np.sum(C))
    name = spectrum.describe().get("model")
    if not total > 0.0 or not np.isfinite(total):
        raise ParameterError(f"roughness spectrum {name!r} has no power on the line's grid q_k = k 2 pi / L "
                             f"(2 pi / L = {params.dq:.6g} .. q_max = {params.q_max:.6g} rad/m)")
    if level == "rms":
        C *= params.h0**2 / total
    elif not spectrum.absolute:
        raise ParameterError(f"roughness_level = 'absolute' is not allowed for the spectrum {name!r}: it is a shape "
                             "without a level of its own; use 'rms'")
    return C


def line_rms(params: Params, spectrum: RoughnessSpectrum | None = None) -> float:
    """Expected RMS height of the generated lines (m): h0 for the ``"rms"`` level, else
    ``sqrt(2 dq sum_k C(q_k))`` of the absolute spectrum on the grid (:func:`grid_psd`)."""
    if spectrum is None:
        if params.level == "rms":
            return params.h0
        spectrum = from_params(params)
    return math.sqrt(2.0 * params.dq * float(np.sum(grid_psd(params, spectrum))))


def linear_force_psd(params: Params, spectrum: RoughnessSpectrum) -> np.ndarray:
    """Eq 39 for any model: the linear MDR force PSD ``C_F(q_k) = k_c^2 sinc^2(q_k a) C_1D(q_k)`` (N^2 m)
    on the grid q_k = k dq, k = 0..n/2, with the generated lines' C_1D (:func:`grid_psd`) and
    ``physics.force_psd_linear``; for the power law it is eq 40."""
    q = params.dq * np.arange(params.n_points // 2 + 1, dtype=np.float64)
    return physics.force_psd_linear(q, grid_psd(params, spectrum), params.E_star, params.a)


def mode_amplitude_table(params: Params, spectrum: RoughnessSpectrum) -> np.ndarray:
    """Amplitudes ``a_k = B(q_k) = sqrt(2 pi / L C_1D(q_k))`` (m), k = 0..n/2 (eq 17), of
    :func:`grid_psd`: the table the line kernel takes instead of its in-kernel power law."""
    return np.sqrt(params.dq * grid_psd(params, spectrum))
