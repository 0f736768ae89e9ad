"""Roughness spectra given by a formula: the power law of eq 33, its roll-off, any Python
callable, and a band-limited part of another spectrum (conventions: :mod:`.kinds`)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .. import physics
from ..errors import ParameterError
from .kinds import RoughnessSpectrum, check_kind


class PowerLaw(RoughnessSpectrum):
    """Eq 33 with hard cut-offs: ``C(q) = prefactor |q|^(-2H-1)`` for q_min <= |q| <= q_max.

    ``prefactor`` lambda A (m^(2-2H)); ``None`` for a shape (the level from h0, eq 50). ``kind``
    "mdr" (default) or "profile"; for "areal" the exponent is -2H-2 (``C_2D = A q^(-2H-2)``).
    """

    def __init__(self, H: float, q_min: float, q_max: float, prefactor: float | None = None, kind: str = "mdr"):
        self.H, self.q_min, self.q_max = float(H), float(q_min), float(q_max)
        self.prefactor, self.kind = prefactor, check_kind(kind)
        self.absolute = prefactor is not None
        self.support = (self.q_min, self.q_max)

    def psd(self, q) -> np.ndarray:
        exponent_shift = 1.0 if self.kind == "areal" else 0.0
        q = np.abs(np.asarray(q, dtype=np.float64))
        scale = 1.0 if self.prefactor is None else self.prefactor
        return physics.roughness_psd(q, scale, self.H + 0.5 * exponent_shift, self.q_min, self.q_max)

    def describe(self) -> dict:
        return {"model": "powerlaw", "kind": self.kind, "H": self.H, "q_min": self.q_min, "q_max": self.q_max,
                "prefactor": self.prefactor}


class RollOff(RoughnessSpectrum):
    """Power law with a roll-off (thesis section 7.2): ``C(q) = prefactor max(|q|, q_r)^(-2H-1)``
    for q_low <= |q| <= q_max, else 0: eq 33 above q_r, flat (white) below it.

    ``q_r`` roll-off wavenumber, ``q_low`` lowest wavenumber kept (0: down to the grid's first
    wavenumber 2 pi / L), ``q_max`` (rad/m); ``prefactor`` (m^(2-2H)) or None for a shape.
    """

    kind = "mdr"

    def __init__(self, H: float, q_r: float, q_max: float, prefactor: float | None = None, q_low: float = 0.0):
        self.H, self.q_r, self.q_max, self.q_low = float(H), float(q_r), float(q_max), float(q_low)
        if not 0.0 <= self.q_low < self.q_r < self.q_max:
            raise ParameterError(f"q_r = {q_r!r} rad/m is not allowed: it must lie in ({q_low!r}, q_max = {q_max!r})")
        self.prefactor, self.absolute = prefactor, prefactor is not None
        self.support = (self.q_low, self.q_max)

    def psd(self, q) -> np.ndarray:
        q = np.abs(np.asarray(q, dtype=np.float64))
        scale = 1.0 if self.prefactor is None else self.prefactor
        inside = physics.in_roughness_band(q, max(self.q_low, 1e-300), self.q_max)
        return np.where(inside, scale * np.maximum(q, self.q_r) ** (-2.0 * self.H - 1.0), 0.0)

    def describe(self) -> dict:
        return {"model": "rolloff", "kind": self.kind, "H": self.H, "q_r": self.q_r, "q_max": self.q_max,
                "q_low": self.q_low, "prefactor": self.prefactor}


class FromCallable(RoughnessSpectrum):
    """Any Python callable ``C = func(q)`` (q in rad/m, vectorized; C in m^3, or m^4 for
    "areal"), zero outside ``support``. API only (not serializable into parameters)."""

    def __init__(self, func: Callable, kind: str = "mdr", absolute: bool = False,
                 support: tuple[float, float] = (0.0, math.inf)):
        if not callable(func):
            raise ParameterError(f"roughness function must be callable, got {func!r}")
        self.func, self.kind, self.absolute = func, check_kind(kind), bool(absolute)
        self.support = (float(support[0]), float(support[1]))

    def psd(self, q) -> np.ndarray:
        q = np.abs(np.asarray(q, dtype=np.float64))
        inside = (q >= self.support[0]) & (q <= self.support[1])
        values = np.zeros_like(q)
        values[inside] = np.asarray(self.func(q[inside]), dtype=np.float64)
        if not np.all(np.isfinite(values)) or np.any(values < 0):
            raise ParameterError("roughness function returned negative or non-finite PSD values")
        return values

    def describe(self) -> dict:
        return {"model": "callable", "kind": self.kind, "absolute": self.absolute,
                "function": getattr(self.func, "__qualname__", repr(self.func)), "support": list(self.support)}


class BandLimited(RoughnessSpectrum):
    """Another spectrum kept only on q_lo <= |q| <= q_hi (rad/m): e.g. the short-wave part of a
    spectrum, whose non-linear low-frequency force eq 63 compares with the linear one."""

    def __init__(self, spectrum: RoughnessSpectrum, q_lo: float, q_hi: float = math.inf):
        self.spectrum, self.kind, self.absolute = spectrum, spectrum.kind, spectrum.absolute
        self.support = (max(q_lo, spectrum.support[0]), min(q_hi, spectrum.support[1]))

    def psd(self, q) -> np.ndarray:
        q = np.abs(np.asarray(q, dtype=np.float64))
        inside = (q >= self.support[0] * (1 - physics.BAND_EDGE_TOLERANCE)) & (q <= self.support[1])
        return np.where(inside, self.spectrum.psd(q), 0.0)

    def grid_mdr_psd(self, q, dq: float) -> np.ndarray:
        q = np.abs(np.asarray(q, dtype=np.float64))
        inside = (q >= self.support[0] * (1 - physics.BAND_EDGE_TOLERANCE)) & (q <= self.support[1])
        return np.where(inside, self.spectrum.grid_mdr_psd(q, dq), 0.0)

    def describe(self) -> dict:
        return {"model": "band_limited", "q_lo": self.support[0], "q_hi": self.support[1],
                "of": self.spectrum.describe()}
