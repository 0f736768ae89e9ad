"""Roughness spectra: one interface for the PSD that rough lines are generated from.

Bottom layer (numpy and scipy only, beside :mod:`mdroll.physics`): the line generator
(:mod:`mdroll.ensemble.lines`) reads the models from here.

Conventions (physics.md section 3). A one-dimensional spectrum C(q) (m^3) is two-sided: a
line's mean square is ``<h^2> = integral over q of both signs C(q) dq ~ sum_k (2 pi / L) C(q_k)``.
An areal spectrum C_2D(q) (m^4) of an isotropic surface is normalized as
``<h^2> = integral d^2q C_2D(|q|) = 2 pi integral_0^inf q C_2D(q) dq``. Wavenumbers in rad/m.

Every spectrum says which kind it is:

* ``"mdr"``: the spectrum of the MDR line itself (eq 33: what the generator needs);
* ``"profile"``: of a line scan along the rail, what a roughness trolley measures (EN 15610);
* ``"areal"``: the isotropic areal spectrum C_2D.

and converts explicitly (:meth:`RoughnessSpectrum.mdr_psd`, :meth:`RoughnessSpectrum.profile_psd`):

* areal -> MDR line, Geike's rule (eq 8) ``C_1D(q) = lambda |q| C_2D(|q|)``; with the RMS
  normalization of eq 50 (the line has the surface's RMS) ``lambda = pi`` for every H
  (:data:`GEIKE_LAMBDA`: ``2 integral lambda q C_2D dq = (lambda / pi) <h^2>``);
* areal -> profile, integration across the track:
  ``C_p(q_x) = integral dq_y C_2D(sqrt(q_x^2 + q_y^2)) = 2 integral_0^inf C_2D(q_x cosh t) q_x cosh t dt``;
* for a power law ``C_2D = A q^(-2H-2)`` the two are in the constant ratio
  ``C_1D / C_p = lambda Gamma(H + 1) / (sqrt(pi) Gamma(H + 1/2))`` (:func:`mdr_to_profile_ratio`);
* profile -> MDR line for rail roughness (:data:`RAIL_ASSUMPTION`): a corrugation constant across
  the contact width, ``h(x, y) = h(x)``. The linear force of a 3D Hertz contact of radius a on a
  small perturbation is the perturbation weighted by the flat-punch pressure per unit
  indentation, ``p_1(r) = E* / (pi sqrt(a^2 - r^2))`` (integral 2 E* a = k_c). Integrating p_1 over
  y across the circle gives ``E*`` for every |x| < a, so the force is ``E* integral_{x-a}^{x+a} h dx``,
  exactly the MDR line's linear force (physics.md section 6) with ``h_MDR = h``: the MDR line
  spectrum equals the profile spectrum, ``C_1D = C_p``, and eq 39 applies to the measured
  profile directly.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
from scipy import integrate, special

from .. import physics
from ..params import SPECTRUM_KINDS, ParameterError, Params
from . import tables

#: Geike's factor lambda of C_1D = lambda q C_2D fixed by the RMS normalization (eq 8, eq 50).
GEIKE_LAMBDA = math.pi
#: The assumption that carries a profile (line-scan) spectrum to the MDR line.
RAIL_ASSUMPTION = "corrugation"
#: Reference roughness of a roughness level, L_r = 10 lg(r^2 / r0^2) (m): 1 um.
ROUGHNESS_REFERENCE = 1e-6


def _check_kind(kind) -> str:
    if kind not in SPECTRUM_KINDS:
        raise ParameterError(f"kind = {kind!r} is not allowed: choose one of {list(SPECTRUM_KINDS)}")
    return kind


class RoughnessSpectrum:
    """A roughness spectrum C(q) of a given kind.

    Subclasses implement :meth:`psd` (the spectrum in its own kind: m^3 for "mdr" and "profile",
    m^4 for "areal") and set ``kind``, ``absolute`` (whether the level is physical; a shape
    alone can only be used with the RMS normalization) and ``support`` (q_lo, q_hi), the
    wavenumbers (rad/m) outside which C is zero.
    """

    kind: str = "mdr"
    absolute: bool = False
    support: tuple[float, float] = (0.0, math.inf)

    def psd(self, q) -> np.ndarray:
        raise NotImplementedError

    def describe(self) -> dict:
        """A JSON-ready description (type and parameters)."""
        raise NotImplementedError

    # ------------------------------------------------------------------ conversions
    def mdr_psd(self, q, geike_lambda: float = GEIKE_LAMBDA) -> np.ndarray:
        """C_1D(q) of the MDR line (m^3, two-sided): the spectrum itself for "mdr"; the profile
        spectrum under the rail assumption (corrugation across the contact width, module
        docstring) for "profile"; Geike's rule ``lambda |q| C_2D(|q|)`` (eq 8) for "areal"."""
        q = np.abs(np.asarray(q, dtype=np.float64))
        if self.kind == "areal":
            return geike_lambda * q * self.psd(q)
        return self.psd(q)

    def profile_psd(self, q, geike_lambda: float = GEIKE_LAMBDA) -> np.ndarray:
        """C_p(q) of a line scan along the rail (m^3, two-sided): the spectrum itself for
        "profile" and, by the rail assumption, for "mdr"; for "areal" the integral across the
        track ``2 integral_0^inf C_2D(q cosh t) q cosh t dt`` (scipy.integrate.quad_vec)."""
        q = np.abs(np.asarray(q, dtype=np.float64))
        if self.kind != "areal":
            return self.psd(q)
        return areal_to_profile(self.psd, q, self.support[1])

    def grid_mdr_psd(self, q, dq: float) -> np.ndarray:
        """C_1D on the line's grid q = k dq (rad/m) for generation: :meth:`mdr_psd` at the grid
        points (band spectra distribute each band's power over its bins instead)."""
        return self.mdr_psd(q)

    def mean_square(self, q_lo: float = 0.0, q_hi: float = math.inf, points: int = 20001) -> float:
        """Mean square height of the MDR line from the band q_lo..q_hi (m^2):
        ``2 integral C_1D dq`` on a log grid (trapezoid; C_1D zero outside its support)."""
        lo = max(q_lo, self.support[0], 1e-3)
        hi = min(q_hi, self.support[1], 1e8)
        if not hi > lo:
            return 0.0
        q = np.geomspace(lo, hi, points)
        return 2.0 * float(integrate.trapezoid(self.mdr_psd(q), q))


def areal_to_profile(areal_psd: Callable, q, q_top: float = math.inf) -> np.ndarray:
    """Profile PSD of an isotropic surface (m^3): ``C_p(q) = 2 integral_0^T C_2D(q cosh t) q cosh t dt``
    with ``T = arccosh(q_top / q)`` (C_2D is zero above q_top, rad/m) or 30 (C_2D decaying).

    ``areal_psd``: C_2D(q) (m^4, vectorized over q in rad/m); ``q`` (rad/m, > 0)."""
    q = np.atleast_1d(np.abs(np.asarray(q, dtype=np.float64)))
    out = np.zeros_like(q)
    inside = q < q_top
    if not np.any(inside):
        return out
    qs = q[inside]
    top = np.arccosh(q_top / qs) if math.isfinite(q_top) else np.full_like(qs, 30.0)

    def integrand(s):  # s in [0, 1] maps to t = s * top per wavenumber
        t = s * top
        return 2.0 * areal_psd(qs * np.cosh(t)) * qs * np.cosh(t) * top

    out[inside] = integrate.quad_vec(integrand, 0.0, 1.0, epsrel=1e-8, limit=400)[0]
    return out


def mdr_to_profile_ratio(H: float, geike_lambda: float = GEIKE_LAMBDA) -> float:
    """For an isotropic power law ``C_2D = A q^(-2H-2)``: ``C_1D / C_p = lambda Gamma(H+1) /
    (sqrt(pi) Gamma(H+1/2))`` away from the cut-offs (``C_p = A q^(-2H-1) sqrt(pi)
    Gamma(H+1/2) / Gamma(H+1)``, the integral across the track). Dimensionless."""
    return geike_lambda * special.gamma(H + 1.0) / (math.sqrt(math.pi) * special.gamma(H + 0.5))


class PowerLaw(RoughnessSpectrum):
    """Eq 33 with hard cut-offs: ``C(q) = prefactor |q|^(-2H-1)`` for q_min <= |q| <= q_max.

    ``prefactor`` lambda A (m^(2-2H)); ``None`` for a shape (the level from h0, eq 50). ``kind``
    "mdr" (default) or "profile"; for "areal" the exponent is -2H-2 (``C_2D = A q^(-2H-2)``).
    """

    def __init__(self, H: float, q_min: float, q_max: float, prefactor: float | None = None, kind: str = "mdr"):
        self.H, self.q_min, self.q_max = float(H), float(q_min), float(q_max)
        self.prefactor, self.kind = prefactor, _check_kind(kind)
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


class Tabulated(RoughnessSpectrum):
    """A PSD table (q_j, C_j), interpolated linearly in (log q, log C) between its points and zero
    outside [q_0, q_last]. ``q`` (rad/m, increasing, > 0); ``C`` (m^3, or m^4 for "areal", > 0);
    ``absolute``: whether C is a physical level (a measured PSD is)."""

    def __init__(self, q, C, kind: str = "profile", absolute: bool = True, source: str = ""):
        q = np.asarray(q, dtype=np.float64)
        C = np.asarray(C, dtype=np.float64)
        if q.ndim != 1 or q.shape != C.shape or q.size < 2:
            raise ParameterError(f"a PSD table needs two columns of equal length >= 2, got shapes {q.shape}, {C.shape}")
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(C)) and np.all(q > 0) and np.all(C > 0)):
            raise ParameterError("a PSD table must hold positive finite wavenumbers q (rad/m) and PSD values C")
        if np.any(np.diff(q) <= 0):
            raise ParameterError("a PSD table's wavenumbers q must increase strictly")
        self.q, self.C, self.kind, self.absolute, self.source = q, C, _check_kind(kind), bool(absolute), source
        self.support = (float(q[0]), float(q[-1]))

    def psd(self, q) -> np.ndarray:
        q = np.abs(np.asarray(q, dtype=np.float64))
        inside = (q >= self.q[0]) & (q <= self.q[-1])
        out = np.zeros_like(q)
        out[inside] = np.exp(np.interp(np.log(q[inside]), np.log(self.q), np.log(self.C)))
        return out

    @classmethod
    def from_file(cls, path, kind: str = "profile", absolute: bool = True) -> "Tabulated":
        """Columns q (rad/m), C (m^3; m^4 for "areal") from a CSV (``#`` comments, an optional
        header line) or an NPY array of shape (K, 2)."""
        q, C = read_two_columns(path, "roughness_table")
        return cls(q, C, kind=kind, absolute=absolute, source=str(path))

    def describe(self) -> dict:
        return {"model": "table", "kind": self.kind, "absolute": self.absolute, "source": self.source,
                "q": self.q.tolist(), "C": self.C.tolist()}


class BandLevels(RoughnessSpectrum):
    """1/3-octave roughness levels per wavelength band, as a PSD.

    Definition: the level of band n is ``L_n = 10 lg(r_n^2 / r0^2)`` dB re r0 = 1 um, ``r_n^2`` the
    mean square height of the spectrum inside the band. Bands are IEC 61260 base 10 in
    wavelength: centre ``lambda_n = 10^(n/10)`` mm (nominal 31.5 mm is n = 15: 31.62 mm), edges
    ``lambda_n 10^(+-1/20)`` (:mod:`mdroll.roughness.bands`). The PSD is constant inside each
    band, ``C = r_n^2 / (2 (q_hi - q_lo))`` (two-sided: the band holds q of both signs), so that
    integrating it over a band returns its level exactly; zero outside the bands given.
    ``wavelengths_mm`` nominal or exact centres (mm); ``levels_db`` (dB re 1 um).
    """

    def __init__(self, wavelengths_mm, levels_db, kind: str = "profile", source: str = ""):
        from .bands import band_numbers, wavelength_band_edges_q

        wavelengths_mm = np.asarray(wavelengths_mm, dtype=np.float64)
        levels_db = np.asarray(levels_db, dtype=np.float64)
        if wavelengths_mm.ndim != 1 or wavelengths_mm.shape != levels_db.shape or wavelengths_mm.size < 1:
            raise ParameterError("band levels need two columns of equal length: wavelength (mm), level (dB re 1 um)")
        if not (np.all(np.isfinite(levels_db)) and np.all(wavelengths_mm > 0)):
            raise ParameterError("band levels need positive wavelengths (mm) and finite levels (dB re 1 um)")
        self.n = band_numbers(wavelengths_mm)
        if np.unique(self.n).size != self.n.size:
            raise ParameterError(f"band levels name a 1/3-octave band twice: wavelengths {wavelengths_mm.tolist()} mm")
        order = np.argsort(-self.n)  # decreasing wavelength = increasing q
        self.n, self.levels_db = self.n[order], levels_db[order]
        self.q_lo, self.q_hi = wavelength_band_edges_q(self.n)
        self.band_mean_square = ROUGHNESS_REFERENCE**2 * 10.0 ** (self.levels_db / 10.0)
        self.density = self.band_mean_square / (2.0 * (self.q_hi - self.q_lo))
        if _check_kind(kind) == "areal":
            raise ParameterError("roughness_kind = 'areal' is not allowed for band levels: they are levels of a line "
                                 "(choose 'profile' or 'mdr')")
        self.kind, self.absolute, self.source = kind, True, source
        self.support = (float(self.q_lo.min()), float(self.q_hi.max()))

    def grid_mdr_psd(self, q, dq: float) -> np.ndarray:
        """On the grid q_k = k dq each band's mean square ``r_n^2`` is spread evenly over the bins
        with q_lo <= q_k < q_hi: ``C(q_k) = r_n^2 / (2 count_n dq)``, so that the band integration of
        :mod:`mdroll.roughness.bands` returns the levels exactly; a band without a bin (longer
        than about L / 5) is lost."""
        q = np.abs(np.asarray(q, dtype=np.float64))
        out = np.zeros_like(q)
        for lo, hi, ms in zip(self.q_lo, self.q_hi, self.band_mean_square):
            inside = (q >= lo) & (q < hi)
            count = int(np.count_nonzero(inside))
            if count:
                out[inside] = ms / (2.0 * count * dq)
        return out

    def psd(self, q) -> np.ndarray:
        q = np.abs(np.asarray(q, dtype=np.float64))
        band = np.searchsorted(self.q_hi, q, side="right")
        band = np.minimum(band, self.n.size - 1)
        inside = (q >= self.q_lo[band]) & (q < self.q_hi[band])
        return np.where(inside, self.density[band], 0.0)

    @classmethod
    def from_file(cls, path, kind: str = "profile") -> "BandLevels":
        """Columns wavelength (mm), level (dB re 1 um) from a CSV or an NPY array (K, 2)."""
        wavelengths, levels = read_two_columns(path, "roughness_table")
        return cls(wavelengths, levels, kind=kind, source=str(path))

    def describe(self) -> dict:
        from .bands import band_centres

        return {"model": "bands", "kind": self.kind, "source": self.source,
                "wavelength_mm": (band_centres(self.n) * 1e3).tolist(), "level_db": self.levels_db.tolist()}


def iso3095() -> BandLevels:
    """The EN ISO 3095:2013 rail roughness limit spectrum (1/3-octave levels, dB re 1 um, 2000 mm
    to 0.8 mm), a profile spectrum (:mod:`mdroll.roughness.tables` for the source)."""
    wavelengths, levels = tables.iso3095_limit()
    return BandLevels(wavelengths, levels, kind="profile", source="EN ISO 3095:2013 limit (tables.ISO3095_SOURCE)")


class FromCallable(RoughnessSpectrum):
    """Any Python callable ``C = func(q)`` (q in rad/m, vectorized; C in m^3, or m^4 for
    "areal"), zero outside ``support``. API only (not serializable into parameters)."""

    def __init__(self, func: Callable, kind: str = "mdr", absolute: bool = False,
                 support: tuple[float, float] = (0.0, math.inf)):
        if not callable(func):
            raise ParameterError(f"roughness function must be callable, got {func!r}")
        self.func, self.kind, self.absolute = func, _check_kind(kind), bool(absolute)
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


def read_two_columns(path, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Two float columns from a CSV (``#`` comment lines and one header line allowed; comma,
    semicolon, tab or space separated) or an NPY array of shape (K, 2); ParameterError naming
    ``name`` and the file otherwise."""
    file = Path(path)
    if not file.is_file():
        raise ParameterError(f"{name} = {str(path)!r}: no such file")
    try:
        if file.suffix.lower() == ".npy":
            data = np.load(file, allow_pickle=False)
        else:
            rows = []
            for line in file.read_text().splitlines():
                line = line.strip()
                if not line or line.startswith("#"):
                    continue
                fields = [f for f in line.replace(";", ",").replace("\t", ",").replace(" ", ",").split(",") if f]
                try:
                    rows.append([float(f) for f in fields])
                except ValueError:
                    if rows:
                        raise
                    continue  # the header
            data = np.array(rows, dtype=np.float64)
    except (ValueError, OSError) as exc:
        raise ParameterError(f"{name} = {str(path)!r} cannot be read as two numeric columns: {exc}") from None
    if data.ndim != 2 or data.shape[1] != 2 or data.shape[0] < 1:
        raise ParameterError(f"{name} = {str(path)!r} must hold two numeric columns, got shape {data.shape}")
    return data[:, 0].astype(np.float64), data[:, 1].astype(np.float64)


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
