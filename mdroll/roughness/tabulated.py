"""Roughness spectra given by data: a PSD table, 1/3-octave band levels (and the EN ISO 3095
limit among them), and the two-column files both are read from (conventions: :mod:`.kinds`)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import ParameterError
from . import tables
from .bands import band_centres, band_numbers, wavelength_band_edges_q
from .kinds import ROUGHNESS_REFERENCE, RoughnessSpectrum, check_kind


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
        self.q, self.C, self.kind, self.absolute, self.source = q, C, check_kind(kind), bool(absolute), source
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
        if check_kind(kind) == "areal":
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
        return {"model": "bands", "kind": self.kind, "source": self.source,
                "wavelength_mm": (band_centres(self.n) * 1e3).tolist(), "level_db": self.levels_db.tolist()}


def iso3095() -> BandLevels:
    """The EN ISO 3095:2013 rail roughness limit spectrum (1/3-octave levels, dB re 1 um, 2000 mm
    to 0.8 mm), a profile spectrum (:mod:`mdroll.roughness.tables` for the source)."""
    wavelengths, levels = tables.iso3095_limit()
    return BandLevels(wavelengths, levels, kind="profile", source="EN ISO 3095:2013 limit (tables.ISO3095_SOURCE)")



def read_numbers(file: Path, name: str) -> np.ndarray:
    """The numbers of a CSV (``#`` comment lines and one header line allowed; comma, semicolon,
    tab or space separated; every row as long as the first) or an NPY array of numbers, as float64
    (one row per line); ParameterError naming ``name``, the file and the line otherwise."""
    if file.suffix.lower() == ".npy":
        try:
            data = np.load(file, allow_pickle=False)
        except (ValueError, OSError, EOFError):
            raise ParameterError(f"{name} = {str(file)!r} is not a readable NPY array of numbers (truncated, "
                                 "pickled objects or another format)") from None
        if data.dtype.kind not in "iuf":
            raise ParameterError(f"{name} = {str(file)!r} holds {data.dtype} values, not numbers")
        return data.astype(np.float64)
    try:
        text = file.read_text()
    except UnicodeDecodeError:
        raise ParameterError(f"{name} = {str(file)!r} is not a text table (not UTF-8): give a CSV or an NPY "
                             "file") from None
    rows, header = [], False
    for number, line in enumerate(text.splitlines(), start=1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        fields = [f for f in line.replace(";", ",").replace("\t", ",").replace(" ", ",").split(",") if f]
        try:
            row = [float(f) for f in fields]
        except ValueError:
            if rows or header:
                raise ParameterError(f"{name} = {str(file)!r}, line {number}: {line[:40]!r} is not a row of "
                                     "numbers") from None
            header = True
            continue  # the header
        if rows and len(row) != len(rows[0]):
            raise ParameterError(f"{name} = {str(file)!r}, line {number}: {len(row)} columns, the first row has "
                                 f"{len(rows[0])}")
        rows.append(row)
    return np.array(rows, dtype=np.float64)


def read_two_columns(path, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Two float columns from a CSV (``#`` comment lines and one header line allowed; comma,
    semicolon, tab or space separated) or an NPY array of shape (K, 2); ParameterError naming
    ``name`` and the file otherwise."""
    file = Path(path)
    if not file.is_file():
        raise ParameterError(f"{name} = {str(path)!r}: no such file")
    data = read_numbers(file, name)
    if data.ndim != 2 or data.shape[1] != 2 or data.shape[0] < 1:
        raise ParameterError(f"{name} = {str(path)!r} must hold two numeric columns, got shape {data.shape}")
    return data[:, 0].astype(np.float64), data[:, 1].astype(np.float64)
