"""Plots of ensemble spectra (matplotlib, Agg backend: no display needed)."""

from __future__ import annotations

import numpy as np

from . import physics
from .errors import ParameterError
from .files import save_figure


def plot_psd(result, quantity: str = "accel", path=None, ax=None):
    """Log-log ensemble-mean PSD on omega (rad/s) with a \u00b11 standard-error band, annotated with
    omega_0 (section 4.2), q_min v0 (eq 21), the omega^-(2H+3) slope (eq 23) and eq 40 averaged
    over its modulation periods pi v0 / a (force; for the acceleration, eq 40 through the
    linearized wheel response), with the bins the record cannot resolve shaded
    (:mod:`mdroll.ensemble.resolution`). PSDs per rad/s: C(omega) = C(q)/v0."""
    import matplotlib  # here, not at the top: a run that draws nothing does not load it

    matplotlib.use("Agg")  # before pyplot: no display needed
    import matplotlib.pyplot as plt

    if quantity not in ("accel", "force"):
        raise ParameterError(f"quantity = {quantity!r} is not allowed: choose 'accel' or 'force'")
    p = result.params
    omega = result.omega[1:]
    q = result.q[1:]
    mean = getattr(result, f"{quantity}_psd")[1:] / p.v0
    err = getattr(result, f"{quantity}_psd_stderr")[1:] / p.v0
    eq40 = physics.force_psd_high_band(q, p.lambda_A, p.H, p.q_min, p.q_max, p.E_star, p.a) / p.v0
    theory = np.where(eq40 > 0, period_average(eq40, q, p.a), 0.0)
    if quantity == "accel":
        theory = theory * physics.acceleration_transfer(omega, p.k_contact, p.m)
    unit = "N$^2$ s/rad" if quantity == "force" else "(m/s$^2$)$^2$ s/rad"
    label = "force" if quantity == "force" else "acceleration"
    unresolved = result.resolution.mask(quantity)[1:]

    own = ax is None
    if own:
        fig, ax = plt.subplots(figsize=(8, 5), dpi=120, layout="constrained")
    lower, upper = np.maximum(mean - err, mean * 1e-3), mean + err
    positive = theory > 0
    drawn = column_extremes(omega, (lower, mean, upper, np.where(positive, theory, np.nan)))
    ax.fill_between(omega[drawn], lower[drawn], upper[drawn], color="C0", alpha=0.3, lw=0)
    ax.loglog(omega[drawn], mean[drawn], color="C0", lw=0.6,
              label=f"ensemble mean ({result.n_real} realizations, {result.algorithm}, {result.mode})")
    shown = drawn[positive[drawn]]
    ax.loglog(omega[shown], theory[shown], color="C3", lw=1.0, alpha=0.8,
              label=r"eq 40, averaged over its modulation periods $\pi v_0 / a$")
    if unresolved.any():
        ax.fill_between(omega, 0, 1, where=unresolved, transform=ax.get_xaxis_transform(), color="0.5", alpha=0.25,
                        lw=0, step="mid", label=f"unresolved by this record ({int(unresolved.sum())} bins)")
    omega_0 = p.omega_0
    omega_t = physics.transition_frequency(p.q_min, p.v0)
    ax.axvline(omega_0, color="k", ls="--", lw=0.8)
    ax.text(omega_0, ax.get_ylim()[1], r" $\omega_0$", va="top")
    ax.axvline(omega_t, color="0.4", ls=":", lw=0.8)
    ax.text(omega_t, ax.get_ylim()[1], r" $q_{min} v_0$", va="top", color="0.4")
    # slope guide omega^-(2H+3), anchored to the mean at 2 q_min
    anchor = np.argmin(np.abs(q - 2 * p.q_min))
    guide = omega[[anchor, min(anchor + max(2, len(omega) // 4), len(omega)) - 1]]  # a straight line: its ends
    slope = physics.power_law_exponent(p.H)
    ax.loglog(guide, 3 * mean[anchor] * (guide / guide[0]) ** slope, color="C2", lw=1.2,
              label=f"$\\omega^{{{slope:.1f}}}$ (eq 23)")
    ax.set_xlabel(r"$\omega$ (rad/s)")
    ax.set_ylabel(f"{label} PSD $C(\\omega)$ ({unit})")
    window = {True: "Hann window", False: "no window (thesis)", None: "window not recorded"}[result.window]
    ax.set_title(f"{label} spectrum: H = {p.H:g}, h$_0$ = {p.h0 * 1e6:g} \u00b5m, L = {p.length:g} m, "
                 f"{result.boundary} boundary, {window}", fontsize=9)
    ax.legend(loc="lower left", fontsize=7)
    if own:
        if path is not None:
            save_figure(fig, path)
            plt.close(fig)
        return fig
    return ax


def period_average(values: np.ndarray, q: np.ndarray, a: float) -> np.ndarray:
    """``values`` on the uniform grid ``q`` (rad/m) averaged over one modulation period pi / a
    (eq 26) centred on each bin: eq 40's band average, which the eye compares with a spectrum
    without its comb of sin^2(q a) zeros hiding the data."""
    step = float(q[1] - q[0]) if q.size > 1 else 1.0
    width = max(1, int(round(np.pi / a / step)))
    if width == 1:
        return values
    total = np.concatenate(([0.0], np.cumsum(values)))
    lo = np.clip(np.arange(values.size) - width // 2, 0, values.size)
    hi = np.clip(lo + width, 0, values.size)
    return (total[hi] - total[lo]) / (hi - lo)


#: Columns of equal width in log x that :func:`column_extremes` keeps the extremes of: several
#: per pixel of the 8-inch figures at 120 dpi.
PLOT_COLUMNS = 4096


def column_extremes(x: np.ndarray, series, columns: int = PLOT_COLUMNS) -> np.ndarray:
    """Sorted indices of the first, last, lowest and highest point of each series in each of
    ``columns`` equal steps of log x (x positive, increasing; NaN points ignored): lines and
    bands through these points draw as through all of them wherever a step is at most a pixel
    wide (M4 aggregation), with ~10^4 points instead of the ~5e5 bins of a thesis-scale
    spectrum (the drawing time it saves: docs/performance.md, the CPU's full run)."""
    log_x = np.log(x)
    column = np.minimum(((log_x - log_x[0]) / max(log_x[-1] - log_x[0], 1e-300) * columns).astype(np.int64),
                        columns - 1)
    starts = np.flatnonzero(np.r_[True, column[1:] != column[:-1]])
    lengths = np.diff(np.r_[starts, x.size])
    keep = [starts, starts + lengths - 1]
    for values in series:
        for extreme in (np.fmin, np.fmax):
            per_column = np.repeat(extreme.reduceat(values, starts), lengths)
            keep.append(np.flatnonzero(values == per_column))
    return np.unique(np.concatenate(keep))
