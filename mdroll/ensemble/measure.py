"""Measurements on ensemble-mean spectra: band statistics, slopes, periods and peaks.

Shared by the validation checks (:mod:`mdroll.validation.checks`) and the parameter studies
(:mod:`mdroll.studies`); NumPy only, on host arrays. Spectra follow physics.md section 6: a
two-sided PSD ``C(q_k)`` (unit^2 m) on ``q_k = 2 pi k / L`` (rad/m), with a standard error per
bin from the ensemble. Band averages span whole modulation periods pi/a in q (eq 26).
"""

from __future__ import annotations

import math

import numpy as np

from .. import physics

#: Standard errors added to a model allowance before a measured value is said to disagree.
Z_SIGMA = 3.0


def period_bands(q: np.ndarray, q_lo: float, q_hi: float, a: float) -> list[np.ndarray]:
    """Masks of consecutive whole modulation periods [q_lo + j pi/a, q_lo + (j+1) pi/a) up to q_hi
    (the period of eq 26, :func:`mdroll.physics.modulation_period`)."""
    period = physics.modulation_period(a)
    count = int(math.floor((q_hi - q_lo) / period * (1 + 1e-12)))
    return [(q >= q_lo + j * period) & (q < q_lo + (j + 1) * period) for j in range(count)]


def paired_ratio(x: np.ndarray, y) -> tuple[float, float]:
    """``mean(x) / mean(y)`` of per-realization values (y an array of the same realizations, or a
    constant) and its relative standard error, from the scatter of ``x_i - ratio y_i``."""
    y = np.broadcast_to(np.asarray(y, dtype=np.float64), x.shape)
    ratio = x.mean() / y.mean()
    residual = x - ratio * y
    return float(ratio), float(residual.std(ddof=1) / math.sqrt(x.size) / x.mean())


def independent_ratio(mean_x: float, rel_x: float, mean_y: float, rel_y: float) -> tuple[float, float]:
    """Ratio of two independent estimates and its relative standard error (in quadrature)."""
    return mean_x / mean_y, math.hypot(rel_x, rel_y)


def band_sum(mean: np.ndarray, stderr: np.ndarray, mask: np.ndarray) -> tuple[float, float]:
    """Sum of an ensemble-mean PSD over the bins of ``mask`` and its relative standard error,
    bins taken as independent (the bins of a stationary series' periodogram nearly are)."""
    total = float(mean[mask].sum())
    return total, math.sqrt(float((stderr[mask] ** 2).sum())) / total


def binned_ratio(mean, stderr, reference_mean, reference_stderr, mask) -> tuple[float, float]:
    """Ratio of band sums of two independent ensembles' mean PSDs over ``mask`` and its relative
    standard error, bins taken as independent. For two ensembles of the same lines the errors
    are positively correlated and this standard error is an upper bound."""
    return independent_ratio(*band_sum(mean, stderr, mask), *band_sum(reference_mean, reference_stderr, mask))


def period_averaged_slope(q: np.ndarray, psd: np.ndarray, a: float, q_lo: float, q_hi: float,
                          stderr: np.ndarray | None = None) -> tuple[float, float]:
    """Least-squares slope of log(PSD averaged over whole modulation periods) against log(q), and
    its standard error (nan without ``stderr``).

    Periods run between consecutive zeros of sin^2(q a) (eq 26; ``a`` the contact radius, m),
    from the first at or above ``q_lo`` (rad/m) up to ``q_hi``. Each period's abscissa is the q
    whose power equals the period's mean of ``q^p sin^2(q a)`` over the mean of ``sin^2(q a)`` at
    the fitted slope p, iterated to a fixed point: with the period's centre instead, the
    convexity of q^p over a period biases the slope (by -0.04 at p = -4.4 on [1.5, 8] q_min).
    With ``stderr`` (per bin, as ``psd``) the fit is weighted by each period mean's relative
    standard error, and the slope's standard error comes from the weights (bins independent).
    """
    first_zero = math.ceil(q_lo * a / math.pi - 1e-9) * math.pi / a
    bands = [m for m in period_bands(q, first_zero, q_hi, a) if m.any()]
    y = np.log([psd[m].mean() for m in bands])
    if stderr is None:
        weights = np.ones_like(y)
    else:
        weights = 1.0 / np.array([band_sum(psd, stderr, m)[1] for m in bands])
    slope = float(np.polyfit(np.log([q[m].mean() for m in bands]), y, 1, w=weights)[0])
    for _ in range(50):
        modulation = [np.sin(q[m] * a) ** 2 for m in bands]
        x = np.log([np.sum(q[m] ** slope * w) / np.sum(w) for m, w in zip(bands, modulation)]) / slope
        fit, cov = np.polyfit(x, y, 1, w=weights, cov="unscaled")
        slope, previous = float(fit[0]), slope
        if abs(slope - previous) < 1e-12:
            break
    return slope, (float(math.sqrt(cov[0, 0])) if stderr is not None else math.nan)


def modulation_period(q: np.ndarray, psd: np.ndarray, H: float, q_lo: float, q_hi: float) -> float:
    """Period (rad/m) of the autocorrelation of C_F q^(2H+3) on [q_lo, q_hi] (rad/m): the first
    maximum after the first minimum, refined by a parabola through the three bins around it."""
    mask = (q >= q_lo * (1 - 1e-12)) & (q <= q_hi)
    y = psd[mask] * q[mask] ** (2 * H + 3)
    y = y - y.mean()
    corr = np.correlate(y, y, mode="full")[y.size - 1:]
    dips = np.where((corr[1:-1] < corr[:-2]) & (corr[1:-1] <= corr[2:]))[0] + 1
    peaks = np.where((corr[1:-1] > corr[:-2]) & (corr[1:-1] >= corr[2:]))[0] + 1
    k = int(peaks[peaks > dips[0]][0])
    c0, c1, c2 = corr[k - 1], corr[k], corr[k + 1]
    lag = k + 0.5 * (c0 - c2) / (c0 - 2 * c1 + c2)
    return float(lag * (q[1] - q[0]))


def resonance_peak(omega: np.ndarray, psd: np.ndarray, omega_0: float, lo: float = 0.5, hi: float = 2.0) -> float:
    """Angular frequency (rad/s) of the largest PSD bin in [lo, hi] omega_0 (``omega_0`` in
    rad/s), refined by a parabola through log PSD of its two neighbours."""
    idx = np.where((omega >= lo * omega_0) & (omega <= hi * omega_0))[0]
    k = int(idx[np.argmax(psd[idx])])
    c0, c1, c2 = np.log(psd[k - 1:k + 2])
    shift = 0.5 * (c0 - c2) / (c0 - 2 * c1 + c2)
    return float(omega[k] + shift * (omega[1] - omega[0]))
