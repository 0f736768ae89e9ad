"""The one figure writer of the experiments: a :class:`Figure` draws itself on a Matplotlib
figure; :func:`write_figure` renders it off-screen (Agg) and writes the PNG atomically."""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from ..files import atomic_write


@dataclass
class Figure:
    """A figure of an experiment: ``draw(fig)`` fills a Matplotlib Figure of ``size`` inches;
    saved as ``<name>.png``."""

    name: str
    caption: str
    draw: Callable
    size: tuple = (7.0, 4.5)
    dpi: int = 100


def render_png(figure: Figure) -> bytes:
    """The PNG bytes of ``figure`` (constrained layout, Agg backend)."""
    import matplotlib  # imported here: its start-up cost is paid only by runs that plot

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=figure.size, layout="constrained")
    try:
        figure.draw(fig)
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png", dpi=figure.dpi)
    finally:
        plt.close(fig)
    return buffer.getvalue()


def write_figure(figure: Figure, target) -> Path | None:
    """Write ``figure`` as PNG to ``target``: a path (written atomically; returned) or a binary file."""
    data = render_png(figure)
    if hasattr(target, "write"):
        target.write(data)
        return None
    path = Path(target)
    with atomic_write(path) as file:
        file.write(data)
    return path


def write_figures(figures, folder) -> list[Path]:
    """Each of ``figures`` as ``<folder>/<name>.png``; the paths."""
    return [write_figure(figure, Path(folder) / f"{figure.name}.png") for figure in figures]
