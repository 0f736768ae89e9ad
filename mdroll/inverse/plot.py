"""Plot of a fit: the band's data against the fitted model, and the residuals P / S."""

from __future__ import annotations

import numpy as np
import scipy.stats

from ..files import save_figure


def plot_fit(result, path=None):
    """Two panels: the data and the model (log-log, two-sided PSD per rad/s on omega) and the ratio
    data / model with the 95 % band of a Gamma(kappa) bin; saved as PNG to ``path`` (a path or a
    binary file) when given."""
    import matplotlib  # here, not at the top: a fit that draws nothing does not load it

    matplotlib.use("Agg")  # before pyplot: no display needed
    import matplotlib.pyplot as plt

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 7), sharex=True, height_ratios=[3, 1.4])
    unit = "(m/s$^2$)$^2$ s/rad" if result.quantity == "accel" else "N$^2$ s/rad"
    top.loglog(result.omega, result.data, lw=0.6, color="0.5", label=f"data (K = {result.passes})")
    top.loglog(result.omega, result.model, lw=0.9, color="C3", label="fitted model")
    top.set_ylabel(f"PSD, {unit}")
    top.legend(loc="lower left")
    top.set_title("  ".join(f"{n} = {result.estimates[n]:.4g}" for n in result.free if n in ("H", "q_min", "a", "h0",
                                                                                                 "E_star")), fontsize=8)
    ratio = result.data / result.model
    bottom.semilogx(result.omega, ratio, ",", color="0.3")
    gamma = scipy.stats.gamma(result.kappa, scale=1.0 / result.kappa)
    for level in (0.025, 0.975):
        bottom.axhline(gamma.ppf(level), color="C0", lw=0.8, ls="--")
    bottom.axhline(1.0, color="C3", lw=0.8)
    bottom.set_yscale("log")
    bottom.set_ylim(max(1e-3, np.nanmin(ratio) * 0.8), np.nanmax(ratio) * 1.2)
    bottom.set_xlabel(r"$\omega$, rad/s")
    bottom.set_ylabel("data / model")
    fig.tight_layout()
    if path is not None:
        save_figure(fig, path, dpi=120)
        plt.close(fig)
    return fig
