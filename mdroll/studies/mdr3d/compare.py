"""The comparison of two force series ensembles: PSDs, the MDR-to-3-D ratio per band with its
confidence interval, and the measured contact filter in 1/3-octave bands.

Spectra: the Hann-windowed periodogram of each realization's series
(:func:`mdroll.ensemble.psd.psd_rows`, physics.md section 6), at ``q_k = 2 pi k / (P dx)``. Bands
(all on the 3-D contact's a_x unless said):

* ``low``: ``2 dq <= q <= q_min - 3 dq`` (below the cut-off, clear of the window's main lobe at
  q_min): the non-linear band of eq 48;
* ``high``: whole modulation periods pi/a_x (eq 26) from ``q_min + 3 dq`` up to ``q_top``;
* ``dips``: the bins of the high band within 0.15 pi of the MDR variant's own zeros
  ``q a = j pi`` (eq 40's sin^2 dips), a its contact half-length.

The ratio of a band is the ratio of the realizations' mean band powers, MDR over 3-D: paired
(:func:`mdroll.ensemble.measure.paired_ratio`) when the MDR rolls on the same surfaces, else of
independent means; its 95 % interval is ``ratio (1 +- 1.96 s)`` (s the relative standard error),
quoted in dB.
"""

from __future__ import annotations

import math

import numpy as np

from ...ensemble.measure import independent_ratio, paired_ratio, period_bands
from ...ensemble.psd import psd_rows, to_host, wavenumbers
from ...roughness.bands import band_mean_squares, wavelength_band_edges_q, wavelength_bands_of_grid

#: Standard errors of the 95 % interval.
Z95 = 1.96
#: Bins kept clear of the cut-off q_min on either side (the Hann window's main lobe is 2 bins).
GUARD = 3
#: Half-width of a dip, in units of pi of q a.
DIP_HALF_WIDTH = 0.15
BANDS = ("low", "high", "dips")


def psds(series, dx: float, device: str) -> tuple[np.ndarray, np.ndarray]:
    """(q (rad/m), per-realization two-sided PSDs (B, P//2 + 1)) of the series (B, P) (host)."""
    rows = to_host(psd_rows(np.ascontiguousarray(series), dx, device, window=True))
    return wavenumbers(series.shape[1], dx), rows


def masks(q: np.ndarray, q_min: float, q_top: float, semi_x: float, mdr_radius: float) -> dict:
    """Boolean masks of the bands (module docstring) on the wavenumbers q."""
    dq = q[1] - q[0]
    periods = period_bands(q, q_min + GUARD * dq, q_top, semi_x)
    high = np.any(periods, axis=0) if periods else np.zeros(q.shape, bool)
    phase = q * mdr_radius / math.pi
    dips = high & (np.abs(phase - np.rint(phase)) <= DIP_HALF_WIDTH) & (np.rint(phase) >= 1)
    return {"low": (q >= 2 * dq) & (q <= q_min - GUARD * dq), "high": high, "dips": dips}


def band_ratio(mdr: np.ndarray, bem: np.ndarray, mask: np.ndarray, paired: bool) -> dict:
    """The MDR-to-3-D ratio of the band ``mask`` from per-realization PSDs (B, bins): ratio, its
    relative standard error, the 95 % interval, the ratio in dB and both mean band powers (N^2);
    None values for a band of fewer than two bins."""
    if mask.sum() < 2:
        return {"ratio": None, "rel_stderr": None, "dB": None, "ci95_dB": None, "bins": int(mask.sum()),
                "mdr_power": None, "bem_power": None}
    y, x = mdr[:, mask].sum(axis=1), bem[:, mask].sum(axis=1)
    if paired:
        ratio, rel = paired_ratio(y, x)
    else:
        count = math.sqrt(x.size)
        ratio, rel = independent_ratio(y.mean(), y.std(ddof=1) / count / y.mean(), x.mean(),
                                       x.std(ddof=1) / count / x.mean())
    low, high = ratio * max(1.0 - Z95 * rel, 1e-6), ratio * (1.0 + Z95 * rel)
    return {"ratio": ratio, "rel_stderr": rel, "dB": 10.0 * math.log10(ratio),
            "ci95_dB": [10.0 * math.log10(low), 10.0 * math.log10(high)], "bins": int(mask.sum()),
            "mdr_power": float(y.mean()), "bem_power": float(x.mean())}


def period_ratios(mdr: np.ndarray, bem: np.ndarray, q: np.ndarray, q_min: float, q_top: float, semi_x: float,
                  paired: bool) -> list:
    """The ratio of :func:`band_ratio` in each whole modulation period pi/a_x of the high band,
    with the period's centre ``q a_x`` (the high band resolved by period)."""
    out = []
    for mask in period_bands(q, q_min + GUARD * (q[1] - q[0]), q_top, semi_x):
        entry = band_ratio(mdr, bem, mask, paired)
        out.append({"qa": float(q[mask].mean() * semi_x) if mask.any() else None, **entry})
    return out


def filter_bands(q: np.ndarray, q_min: float, q_top: float) -> np.ndarray:
    """Wavelength band numbers (longest first) wholly on the grid from 2 dq up to q_top, above
    q_min (where the roughness is; force and roughness share the window's leakage, which cancels
    in their ratio to first order) and holding at least one grid wavenumber."""
    dq = q[1] - q[0]
    bands = wavelength_bands_of_grid(dq, q_top)
    lo, hi = wavelength_band_edges_q(bands)
    _, counts = band_mean_squares(q, np.ones_like(q), dq, lo, hi)
    return bands[(lo >= max(q_min, 2.0 * dq)) & (counts > 0)]


def measured_filter(q: np.ndarray, force_psd: np.ndarray, rough_psd: np.ndarray, stiffness: float, bands) -> list:
    """The measured contact filter (dB) per band: ``10 lg(ms_F / (k^2 ms_r))`` from the ensemble
    means of the force and profile-roughness PSDs (band mean squares of
    :func:`mdroll.roughness.bands.band_mean_squares`)."""
    dq = q[1] - q[0]
    edges = wavelength_band_edges_q(bands)
    force, _ = band_mean_squares(q, force_psd.mean(axis=0), dq, *edges)
    rough, _ = band_mean_squares(q, rough_psd.mean(axis=0), dq, *edges)
    return (10.0 * np.log10(force / (stiffness * stiffness * rough))).tolist()
