"""The spectral measurements the studies share: band averages over whole modulation periods,
the plateau level of a periodic run and where the spectrum leaves it."""

from __future__ import annotations

import math

import numpy as np

from ..ensemble.measure import band_sum
from ..params import Params
from .closed_forms import line_psd, low_band


def plateau_band(p: Params, q: np.ndarray) -> np.ndarray:
    """Bins of the low-band plateau fit: ``0 < q <= min(q_min / 2, pi / (2a))``, below q_min
    (eq 48 is the whole force there) and before the first zero of cos^2(q a)."""
    return (q > 0) & (q <= min(p.q_min / 2, math.pi / (2 * p.a)))


def plateau_level(result) -> tuple[float, float, float]:
    """The q -> 0 plateau of the force PSD, ``C_F0`` (N^2 m), of a periodic run: the closed-form
    low band's shape, normalized to 1 at q = 0, fitted by one factor to the ensemble mean over
    :func:`plateau_band` (``C_F0 = sum C_F / sum shape``). Returns ``(C_F0, its relative standard
    error, the closed form's own value at q = 0)``. The shape (the cos^2(q a) dip and the
    self-convolution of C_1D) is the closed form's; the level is measured."""
    p = result.params
    if result.boundary != "periodic":
        raise ValueError("plateau_level needs a periodic run (its bins are the line's own modes)")
    mask = plateau_band(p, result.q)
    psd_of_line = line_psd(p)
    at_zero = float(low_band(p, np.zeros(1), psd_of_line)[0])
    shape = low_band(p, result.q[mask], psd_of_line) / at_zero
    total, rel = band_sum(result.force_psd, result.force_psd_stderr, mask)
    return total / float(shape.sum()), rel, at_zero


#: Bins of the running median the transition is found on: one bin of a small ensemble can
#: exceed the threshold by chance (2 realizations: one in ~2000 bins), three of five do not.
TRANSITION_MEDIAN_BINS = 5


def transition_wavenumber(q: np.ndarray, psd: np.ndarray, level: float, factor: float = 10.0) -> float:
    """The first wavenumber (rad/m) at which the running median of ``psd`` (over
    :data:`TRANSITION_MEDIAN_BINS` bins) exceeds ``factor`` times the low-band ``level`` (same
    units): where the spectrum leaves its non-linear plateau (eq 21)."""
    from scipy.signal import medfilt

    above = np.nonzero(medfilt(psd, TRANSITION_MEDIAN_BINS) > factor * level)[0]
    return float(q[above[0]]) if above.size else math.nan


def period_edges(q_lo: float, q_hi: float, a: float) -> list[tuple[float, float]]:
    """Whole modulation periods ``[j pi/a, (j+1) pi/a)`` (rad/m; eq 26, ``a`` in m) from the first
    zero of sin^2(q a) at or above ``q_lo`` up to ``q_hi``."""
    period = math.pi / a
    first = math.ceil(q_lo / period - 1e-9)
    last = math.floor(q_hi / period + 1e-9)
    return [(j * period, (j + 1) * period) for j in range(first, last)]


def band_slices(q: np.ndarray, edges) -> list[slice]:
    """The bins ``lo <= q < hi`` of each band of ``edges`` as slices of the sorted ``q``."""
    bounds = np.searchsorted(q, np.asarray(edges, dtype=np.float64).ravel(), side="left").reshape(-1, 2)
    return [slice(int(a), int(b)) for a, b in bounds]


def band_means(q: np.ndarray, psd: np.ndarray, stderr: np.ndarray, edges) -> tuple[np.ndarray, np.ndarray]:
    """Mean PSD over the bins of each band ``[lo, hi)`` of ``edges`` (a density: comparable
    between runs of different lengths) and its relative standard error (bins independent)."""
    means, rels = [], []
    for band in band_slices(q, edges):
        total = float(psd[band].sum())
        means.append(total / max(1, band.stop - band.start))
        rels.append(math.sqrt(float((stderr[band] ** 2).sum())) / total)
    return np.array(means), np.array(rels)
