"""Preparing a batch of lines for an algorithm's force kernels (physics.md section 4): where the
wheel rolls (:mod:`mdroll.forces.steps`), the wrapped copy of a periodic line, and the data the
algorithm's registry entry needs (row bounds, prefix sums, min/max tree;
:mod:`mdroll.forces.prepared`)."""

from __future__ import annotations

from ..devices import to_warp
from ..errors import ParameterError
from ..params import Params
from .algorithm import BOUNDS, PREFIX, TREE
from .indenter import indenter_curvature, reach
from .prepared import (DEFAULT_BAND_LIMIT, DEFAULT_LEAF_SIZE, PreparedLines, batch_bounds, min_max_tree, periodic_copy,
                       prefix_sums, row_bounds)
from .registry import algorithm_entry
from .steps import step_range, wheel_margin


def prepare_lines(
    lines,
    params: Params,
    algorithm: str,
    boundary: str,
    d: float,
    device: str,
    leaf_size: int = DEFAULT_LEAF_SIZE,
    h_max: float | None = None,
    band_limit: int = DEFAULT_BAND_LIMIT,
) -> PreparedLines:
    """Bounds, wrapped copy, prefix sums and tree as the algorithm needs them (see PreparedLines).

    ``h_max`` (m) places the open-boundary wheel and sizes the periodic wrap
    (:func:`~mdroll.forces.steps.step_range`); by default it is the largest height of ``lines``.
    Forces stay exact whatever it is: springs off an open line do not exist, and the window of
    each line is taken from its own maximum.
    """
    entry = algorithm_entry(algorithm)
    lines = to_warp(lines, device)  # a view of a Warp, CuPy or (on the CPU) NumPy array
    n = lines.shape[1]
    # the row bounds and the largest height of all rows (one host copy): for the default h_max
    # and the windows of the algorithms that need them; a tree's root holds them once h_max is
    # given (one pass over the lines fewer)
    bounds = h_top = h_low = None
    if h_max is None or (BOUNDS in entry.needs and TREE not in entry.needs):
        bounds = row_bounds(lines, device)
        h_low, h_top = batch_bounds(bounds)
    if h_max is None:
        h_max = h_top
    first, steps = step_range(params, boundary, d, h_max)
    work = lines
    if boundary == "periodic":
        first = wheel_margin(params, d, h_max)
        if 2 * first + 1 > n:  # the wrapped copy would repeat the line: a window wider than the line
            raise ParameterError(
                f"L = {params.L!r} m is too short for the periodic boundary at d = {d:.4g} m, max h = {h_max:.4g} m: "
                f"the window of possible contact spans {2 * first + 1} springs, more than the {n} on the line"
            )
        work = periodic_copy(lines, first, device)
    prepared = PreparedLines(lines=work, n_work=work.shape[1], first=first, steps=steps, bounds=bounds, leaf_size=leaf_size,
                             band_limit=band_limit)
    if PREFIX in entry.needs:
        prepared.prefix, prepared.prefix_owner = prefix_sums(work, device)
    if TREE in entry.needs:
        prepared.tree, prepared.level_offsets, prepared.top_level, root = min_max_tree(work, leaf_size, device)
        if prepared.bounds is None:
            prepared.bounds = root
            h_low, h_top = batch_bounds(root)
    if BOUNDS in entry.needs:
        # each line's window comes from its own maximum (the kernels read ``bounds``), not h_max
        prepared.h_top, prepared.h_low = h_top, h_low
    if entry.max_window is not None:
        window = reach(d + prepared.h_top, indenter_curvature(params))
        if window > entry.max_window:
            raise ParameterError(
                f"dx = {params.dx!r} m is too fine for the {algorithm} kernel: the contact window spans {window} springs "
                f"a side, beyond the {entry.max_window} for which its float64 closed-form sums of squares are exact"
            )
    return prepared
