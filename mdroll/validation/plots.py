"""Plot callbacks of the checks: each draws its figure on a Matplotlib Axes when the report asks."""

from __future__ import annotations

import numpy as np


def spectrum_plot(x, curves, xlabel="q (rad/m)", ylabel="C_F (N^2 m)", marks=()):
    """A plot callback: log-log curves ``(label, y, stderr or None)`` on ``x`` and vertical marks
    ``(label, position)``."""
    def draw(ax):
        for label, y, err in curves:
            keep = (x > 0) & (y > 0)
            line, = ax.loglog(x[keep], y[keep], lw=0.8, label=label)
            if err is not None:
                ax.fill_between(x[keep], np.maximum(y - err, y * 1e-3)[keep], (y + err)[keep], color=line.get_color(),
                                alpha=0.25, lw=0)
        for label, position in marks:
            ax.axvline(position, color="0.5", ls=":", lw=0.8)
            ax.text(position, 1.0, label, transform=ax.get_xaxis_transform(), rotation=90, va="top", ha="right",
                    fontsize=7)
        ax.set_xlabel(xlabel)
        ax.set_ylabel(ylabel)
        ax.legend(fontsize=7)
    return draw
