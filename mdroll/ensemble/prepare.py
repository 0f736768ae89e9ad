"""Preparing a batch of lines for the force kernels (physics.md section 4): where the wheel rolls
(:func:`step_range`), the wrapped copy of a periodic line, and the data the algorithm's registry
entry needs (row bounds, prefix sums, min/max tree; :mod:`.algorithms`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import physics
from ..devices import is_cuda, to_warp, warp
from ..params import MAX_POINTS, ParameterError, Params
from .algorithms import BOUNDS, PREFIX, TREE, algorithm_entry, indenter_curvature
from . import buffers
from .arguments import check_choice
from .fft import fast_length

BOUNDARIES = ("open", "periodic")
#: Springs per tree leaf: 32 was fastest at thesis scale on the H200 when leaf sizes were last
#: compared (v4: 14.6 ms vs 15.8 for 8; docs/performance.md).
DEFAULT_LEAF_SIZE = 32
#: Band width (springs a side, from a row's root bounds) above which the tree kernel's main path
#: descends the tree instead of summing the narrowed bands directly (kernels/tree.py). On an
#: H100 (64 lines over 0.25 m, benchmarks/results/tree_tuning_H100_v8.json) the direct sum was
#: faster up to 2^21 springs (row band ~1600: 15.7 vs 17.2 ms) and the descent beyond (2^22,
#: ~3200: 35.3 vs 53.3 ms); at thesis scale (~40) the bands are always summed directly.
DEFAULT_BAND_LIMIT = 2048


def reach(level: float, curvature: float) -> int:
    """Largest m >= 0 with ``curvature m^2 <= level`` (-1 if level < 0); the host twin of
    :func:`mdroll.kernels.common.reach_inclusive`. A level whose window would span more than
    ``MAX_POINTS`` springs (no line holds more), or is not finite, is refused: the loops below
    then stay a few rounding steps long."""
    if level < 0:
        return -1
    root = math.sqrt(level / curvature) if math.isfinite(level) else math.inf
    if not root <= MAX_POINTS:
        raise ParameterError(
            f"indentation plus height {level:.4g} m gives a window of possible contact of {root:.3g} springs a side, "
            f"more than the {MAX_POINTS} any line holds: the heights (h0, or the lines given) are absurd"
        )
    m = int(math.floor(root))
    while m > 0 and curvature * m * m > level:
        m -= 1
    while curvature * (m + 1) * (m + 1) <= level:
        m += 1
    return m


def wheel_margin(params: Params, d: float, h_max: float) -> int:
    """Springs the wheel keeps from either end of an open line (or wraps, periodic).

    The half-width of the window of possible contact, ``max m`` with ``m^2 dx^2 / R <= d + h_max``,
    and at least ``floor(a(d)/dx) + 1`` so that the edge formula's end cells lie on the line.
    """
    curvature = indenter_curvature(params)
    edge_cells = int(math.floor(physics.contact_radius(d, params.R) / params.dx)) + 1
    return max(reach(d + h_max, curvature), edge_cells)


def step_range(params: Params, boundary: str, d: float, h_max: float) -> tuple[int, int]:
    """``(first, steps)``: the wheel's first spring index on the line and the number of steps.

    ``periodic``: the wheel visits every spring, ``x_w = s dx`` for s = 0..n-1 (first = 0).
    ``open`` (the thesis's): the wheel starts at the first spring whose whole window of possible
    contact (``d + h_max``, see :func:`wheel_margin`) lies on the line, so ``x_w`` starts near a,
    and steps one spring at a time while that window stays on the line, for the largest number
    of steps of the form ``2^a 3^b 5^c`` (:func:`mdroll.ensemble.fft.fast_length`): at most
    about 1 % fewer at 10^6 steps, and the series' FFTs run about 3x faster than at a length with
    large prime factors.

    ``d``: the wheel's indentation (m); ``h_max``: the highest roughness on the lines (m).
    Returns ``first`` (a spring index; the wheel's position is ``first dx``, m) and ``steps`` (one
    spring, ``dt = dx / v0`` s, each).
    """
    check_choice("boundary", boundary, BOUNDARIES)
    n = params.n_points
    if boundary == "periodic":
        return 0, n
    margin = wheel_margin(params, d, h_max)
    steps = n - 2 * margin
    if steps < 1:
        raise ParameterError(
            f"L = {params.L!r} m is too short for the open boundary at d = {d:.4g} m, max h = {h_max:.4g} m: "
            f"the window of possible contact spans {2 * margin + 1} springs of the {n} on the line"
        )
    return margin, fast_length(steps)


@dataclass
class PreparedLines:
    """Lines on a device with everything the force kernels read.

    ``lines`` is what the kernels index: the input itself (open) or a copy with ``first``
    wrapped springs on each side (periodic). The wheel of step s sits at spring ``first + s``
    of ``lines``. ``bounds[r] = (min h, max h)`` of row r (None where the algorithm needs no
    bounds and h_max is given); ``prefix`` (R, n_work + 1) holds ``S_j = sum_{i<j} h_i``
    (eq 18) up to a constant per row; ``tree`` the implicit min/max tree. Each is None where the
    algorithm's registry entry does not need it (``needs``, :mod:`.algorithms`).
    """

    lines: object
    n_work: int
    first: int
    steps: int
    bounds: object
    prefix: object = None
    tree: object = None
    level_offsets: object = None
    top_level: int = 0
    leaf_size: int = DEFAULT_LEAF_SIZE
    band_limit: int = DEFAULT_BAND_LIMIT
    h_top: float = 0.0  # the largest height of all rows (m; where the algorithm needs row bounds)
    h_low: float = 0.0  # the lowest height of all rows (m; likewise)
    prefix_owner: object = None  # the flat array behind ``prefix`` (:func:`_prefix_sums`)


def _batch_bounds(bounds) -> tuple[float, float]:
    """The lowest and the largest height (m) of a batch from its row bounds (one host copy)."""
    host = bounds.numpy()
    return float(host[:, 0].min()), float(host[:, 1].max())


def _row_bounds(lines, device, threads: int | None = None):
    """``(min h, max h)`` of each row, a (R,) ``vec2d`` array: ``threads`` a row (default
    BOUNDS_THREADS on CUDA, 1 on the CPU, where Warp runs a launch's threads one after another)
    take strided partials, combined in groups of BOUNDS_GROUP where they divide evenly, then per
    row."""
    from ..kernels.lines import BOUNDS_GROUP, BOUNDS_THREADS, row_min_max, strided_min_max

    wp = warp()
    rows, n = lines.shape
    if threads is None:
        threads = min(BOUNDS_THREADS, n) if is_cuda(device) else 1
    partial = wp.empty((rows, threads), dtype=wp.vec2d, device=device)
    bounds = wp.empty(rows, dtype=wp.vec2d, device=device)
    wp.launch(strided_min_max, dim=(rows, threads), inputs=[lines, n, threads, partial], device=device)
    if threads > BOUNDS_GROUP and threads % BOUNDS_GROUP == 0:
        # the partials in groups first: one thread combining a row's 512 took 0.14 ms of the
        # 1.0 ms at 300 x 2^20 on an H200, waiting on its loads
        groups = threads // BOUNDS_GROUP
        grouped = wp.empty(rows * groups, dtype=wp.vec2d, device=device)
        wp.launch(row_min_max, dim=rows * groups, inputs=[partial.reshape((rows * groups, BOUNDS_GROUP)), BOUNDS_GROUP,
                                                          grouped], device=device)
        partial, threads = grouped.reshape((rows, groups)), groups
    wp.launch(row_min_max, dim=rows, inputs=[partial, threads, bounds], device=device)
    return bounds


def _prefix_sums(lines, device):
    """``S[r, j] - S[r, 0] = sum_{i<j} h[r, i]`` for j = 0..n (eq 18), as a (R, n + 1) Warp view,
    and the flat array that owns its memory.

    One inclusive scan over the whole batch laid end to end, out of place (Warp's
    ``array_scan``: CUB's device scan on CUDA, a sequential loop on the CPU): 1.5 ms at
    300 x 2^20 on an H200, against 3.0 ms for ``cupy.cumsum`` into an output (a copy, then the
    scan in place) and 8.2 ms row by row (docs/performance.md,
    v6a). Row r is the view of the flat prefix from element r n, rows
    overlapping by one element, so S[r, 0] is the sum of the rows before it: every kernel reads
    differences S_j - S_i only, and each line's mean is zero, so that offset stays near rounding
    size (a wrapped periodic copy's few extra springs add ~1e-5 m a row).
    """
    wp = warp()
    lines = to_warp(lines, device)
    rows, n = lines.shape
    flat = buffers.empty("prefix sums", (rows * n + 1,), wp.float64, device)
    flat[:1].zero_()
    wp.utils.array_scan((lines if lines.is_contiguous else lines.contiguous()).flatten(), flat[1:], inclusive=True)
    prefix = wp.array(ptr=flat.ptr, dtype=wp.float64, shape=(rows, n + 1), strides=(8 * n, 8), device=device)
    return prefix, flat


def ensure_prefix_sums(prepared: "PreparedLines", device: str):
    """``prepared.prefix`` (eq 18; see :func:`_prefix_sums`), built on first use for a kernel
    that reads it where the algorithm's registry entry does not need it by default (the sweep's
    CPU and tiles forms and its coupled step: its CUDA stream sums its anchors' cores spring by
    spring)."""
    if prepared.prefix is None:
        prepared.prefix, prepared.prefix_owner = _prefix_sums(prepared.lines, device)
    return prepared.prefix


def tree_levels(n: int, leaf_size: int) -> list[int]:
    """Node counts per level of the implicit tree over n springs, leaves first, root last."""
    counts = [-(-n // leaf_size)]
    while counts[-1] > 1:
        counts.append(-(-counts[-1] // 2))
    return counts


def _min_max_tree(lines, leaf_size: int, device):
    """The implicit (min h, max h) tree of each row (kernels/tree.py), its level offsets (device
    int32), its top level, and its root per row: the row bounds, as a (R,) ``vec2d`` array."""
    from ..kernels import common
    from ..kernels.lines import row_min_max, segment_min_max, tree_parents

    wp = warp()
    rows, n = lines.shape
    counts = tree_levels(n, leaf_size)
    top_level = len(counts) - 1
    # the traversal's stack bound (kernels/tree.py): 2 + start level <= 2 + top level
    capacity = common.tree_stack._length_
    if top_level + 2 > capacity:
        raise ParameterError(
            f"leaf_size = {leaf_size} gives a tree of {top_level + 1} levels over {n} springs; its traversal "
            f"needs a stack of {top_level + 2} > {capacity}: use a larger leaf_size"
        )
    offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32)
    tree = wp.empty((rows, int(offsets[-1])), dtype=wp.vec2d, device=device)
    wp.launch(segment_min_max, dim=(rows, counts[0]), inputs=[lines, n, leaf_size, tree], device=device)
    for level in range(1, len(counts)):
        wp.launch(
            tree_parents,
            dim=(rows, counts[level]),
            inputs=[tree, int(offsets[level - 1]), counts[level - 1], int(offsets[level])],
            device=device,
        )
    root = wp.empty(rows, dtype=wp.vec2d, device=device)
    top = int(offsets[top_level])
    wp.launch(row_min_max, dim=rows, inputs=[tree[:, top:top + 1], 1, root], device=device)
    return tree, wp.array(offsets[:-1], dtype=wp.int32, device=device), top_level, root


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
    (:func:`step_range`); by default it is the largest height of ``lines``. Forces stay exact
    whatever it is: springs off an open line do not exist, and the window of each line is
    taken from its own maximum.
    """
    from ..kernels.lines import periodic_extend

    wp = warp()
    entry = algorithm_entry(algorithm)
    lines = to_warp(lines, device)  # a view of a Warp, CuPy or (on the CPU) NumPy array
    rows, n = lines.shape
    # the row bounds and the largest height of all rows (one host copy): for the default h_max
    # and the windows of the algorithms that need them; a tree's root holds them once h_max is
    # given (one pass over the lines fewer)
    bounds = h_top = h_low = None
    if h_max is None or (BOUNDS in entry.needs and TREE not in entry.needs):
        bounds = _row_bounds(lines, device)
        h_low, h_top = _batch_bounds(bounds)
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
        work = buffers.empty("periodic lines", (rows, n + 2 * first), wp.float64, device)
        wp.launch(periodic_extend, dim=work.shape, inputs=[lines, n, first, work], device=device)
    prepared = PreparedLines(lines=work, n_work=work.shape[1], first=first, steps=steps, bounds=bounds, leaf_size=leaf_size,
                             band_limit=band_limit)
    if PREFIX in entry.needs:
        prepared.prefix, prepared.prefix_owner = _prefix_sums(work, device)
    if TREE in entry.needs:
        prepared.tree, prepared.level_offsets, prepared.top_level, root = _min_max_tree(work, leaf_size, device)
        if prepared.bounds is None:
            prepared.bounds = root
            h_low, h_top = _batch_bounds(root)
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
