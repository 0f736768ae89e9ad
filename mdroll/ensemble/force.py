"""Contact force of a batch of rough lines by the three MDR algorithms (physics.md section 4).

:func:`contact_force` is the entry point; :func:`prepare_lines` does the per-line preprocessing
(bounds, wrapped copy for the periodic boundary, prefix sums, min/max tree) that the dynamics
reuse.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..devices import device_of, is_cuda, resolve_device, to_warp, warp
from ..kernels.common import MAX_CLOSED_FORM_OFFSET
from ..params import ParameterError, Params
from .fft import fast_length

ALGORITHMS = ("tree", "direct", "edge")
BOUNDARIES = ("open", "periodic")
#: Springs per tree leaf: 32 was fastest at thesis scale on the H200 (14.6 ms vs 15.8 for 8;
#: docs/performance.md, v4).
DEFAULT_LEAF_SIZE = 32
#: Band width (springs a side, from a row's root bounds) above which the tree kernel's main path
#: descends the tree instead of summing the narrowed bands directly (kernels/tree.py). On an
#: H100 (64 lines over 0.25 m, benchmarks/results/tree_tuning_H100_v8.json) the direct sum was
#: faster up to 2^21 springs (row band ~1600: 15.7 vs 17.2 ms) and the descent beyond (2^22,
#: ~3200: 35.3 vs 53.3 ms); at thesis scale (~40) the bands are always summed directly.
DEFAULT_BAND_LIMIT = 2048


def check_choice(name: str, value, allowed) -> str:
    if value not in allowed:
        raise ParameterError(f"{name} = {value!r} is not allowed: choose one of {', '.join(allowed)}")
    return value


def reach(level: float, curvature: float) -> int:
    """Largest m >= 0 with ``curvature m^2 <= level`` (-1 if level < 0); the host twin of
    :func:`mdroll.kernels.common.reach_inclusive`."""
    if level < 0:
        return -1
    m = int(math.floor(math.sqrt(level / curvature)))
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
    curvature = params.dx**2 / params.R
    edge_cells = int(math.floor(math.sqrt(d * params.R) / params.dx)) + 1
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
    of ``lines``. ``bounds[r] = (min h, max h)`` of row r (None for edge with a given h_max);
    ``prefix`` (R, n_work + 1) holds
    ``S_j = sum_{i<j} h_i`` (eq 18) up to a constant per row; ``tree`` the implicit min/max tree.
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
    h_top: float = 0.0  # the largest height of all rows (m; direct and tree)
    prefix_owner: object = None  # the flat array behind ``prefix`` (:func:`_prefix_sums`)


def _row_bounds(lines, device):
    from ..kernels.lines import BOUNDS_THREADS, row_min_max, strided_min_max

    wp = warp()
    rows, n = lines.shape
    threads = min(BOUNDS_THREADS, n) if is_cuda(device) else 1
    partial = wp.empty((rows, threads), dtype=wp.vec2d, device=device)
    bounds = wp.empty(rows, dtype=wp.vec2d, device=device)
    wp.launch(strided_min_max, dim=(rows, threads), inputs=[lines, n, threads, partial], device=device)
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
    flat = wp.empty(rows * n + 1, dtype=wp.float64, device=device)
    flat[:1].zero_()
    wp.utils.array_scan((lines if lines.is_contiguous else lines.contiguous()).flatten(), flat[1:], inclusive=True)
    prefix = wp.array(ptr=flat.ptr, dtype=wp.float64, shape=(rows, n + 1), strides=(8 * n, 8), device=device)
    return prefix, flat


def tree_levels(n: int, leaf_size: int) -> list[int]:
    """Node counts per level of the implicit tree over n springs, leaves first, root last."""
    counts = [-(-n // leaf_size)]
    while counts[-1] > 1:
        counts.append(-(-counts[-1] // 2))
    return counts


def _min_max_tree(lines, leaf_size: int, device):
    """The implicit (min h, max h) tree of each row (kernels/tree.py), its level offsets (device
    int32), its top level, and its root per row: the row bounds, as a (R,) ``vec2d`` array."""
    from ..kernels.common import TREE_STACK_CAPACITY
    from ..kernels.lines import row_min_max, segment_min_max, tree_parents

    wp = warp()
    rows, n = lines.shape
    counts = tree_levels(n, leaf_size)
    top_level = len(counts) - 1
    # the traversal's stack bound (kernels/tree.py): 2 + start level <= 2 + top level
    if top_level + 2 > TREE_STACK_CAPACITY:
        raise ParameterError(
            f"leaf_size = {leaf_size} gives a tree of {top_level + 1} levels over {n} springs; its traversal "
            f"needs a stack of {top_level + 2} > {TREE_STACK_CAPACITY}: use a larger leaf_size"
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
    rows, n = lines.shape
    # the row bounds and the largest height of all rows (one host copy): for the default h_max
    # and the direct/tree windows; edge needs neither, and the tree's root holds them once
    # h_max is given (one pass over the lines fewer)
    bounds = h_top = None
    if h_max is None or algorithm == "direct":
        bounds = _row_bounds(lines, device)
        h_top = float(bounds.numpy()[:, 1].max())
    if h_max is None:
        h_max = h_top
    first, steps = step_range(params, boundary, d, h_max)
    work = lines
    if boundary == "periodic":
        first = wheel_margin(params, d, h_max)
        work = wp.empty((rows, n + 2 * first), dtype=wp.float64, device=device)
        wp.launch(periodic_extend, dim=work.shape, inputs=[lines, n, first, work], device=device)
    prepared = PreparedLines(lines=work, n_work=work.shape[1], first=first, steps=steps, bounds=bounds, leaf_size=leaf_size,
                             band_limit=band_limit)
    if algorithm in ("tree", "edge"):
        prepared.prefix, prepared.prefix_owner = _prefix_sums(work, device)
    if algorithm == "tree":
        prepared.tree, prepared.level_offsets, prepared.top_level, root = _min_max_tree(work, leaf_size, device)
        if prepared.bounds is None:
            prepared.bounds = root
            h_top = float(root.numpy()[:, 1].max())
    if algorithm in ("direct", "tree"):
        # each line's window comes from its own maximum (the kernels read ``bounds``), not h_max
        prepared.h_top = h_top
        window = reach(d + prepared.h_top, params.dx**2 / params.R)
        if window > MAX_CLOSED_FORM_OFFSET:
            raise ParameterError(
                f"dx = {params.dx!r} m is too fine for the {algorithm} kernel: the contact window spans {window} springs "
                f"a side, beyond the {MAX_CLOSED_FORM_OFFSET} for which its float64 closed-form sums of squares are exact"
            )
    return prepared


def edge_geometry(params: Params, d: float):
    """The host twin of :func:`mdroll.kernels.edge.edge_geometry`: eq 49's constants at indentation d (m)."""
    from ..kernels.edge import EdgeGeometry

    a = math.sqrt(d * params.R)
    alpha = a / params.dx
    geometry = EdgeGeometry()
    geometry.whole = int(math.floor(alpha))
    geometry.fraction = alpha - geometry.whole
    geometry.hertz = 4.0 * params.E_star * a * a * a / (3.0 * params.R)
    geometry.tip = params.E_star * params.R / (4.0 * a)
    geometry.dx_E_star = params.E_star * params.dx
    return geometry


def lift_table(params: Params, d: float, h_top: float, device: str):
    """The indenter profile ``d - curvature m^2`` (m) at offsets ``|m| <= window + 8`` (the window
    of possible contact for heights up to ``h_top``, plus the blocked sums' padding), as a Warp
    array on ``device``, and the index of m = 0: the table the register-blocked kernels read
    instead of recomputing it. Made by a kernel where it is read: an upload from pageable host
    memory would wait for the device's queue to drain."""
    from ..kernels.common import BLOCK, indenter_lifts

    wp = warp()
    curvature = params.dx**2 / params.R
    reach_out = max(reach(d + h_top, curvature), 0) + BLOCK
    lifts = wp.empty(2 * reach_out + 1, dtype=wp.float64, device=device)
    wp.launch(indenter_lifts, dim=lifts.shape, inputs=[d, curvature, reach_out, lifts], device=device)
    return lifts, reach_out


def launch_force(prepared: PreparedLines, params: Params, algorithm: str, d: float, device: str, out=None,
                 offset: float = 0.0):
    """The (R, steps) array of ``F - offset`` (N, Warp float64 on ``device``): the force at
    constant indentation d (m), less ``offset`` (N; the pipeline passes F_N, so the series
    holds the small deviation that the spectra need).

    ``out``: a preallocated (R, steps) float64 array to write into.
    """
    command, force = force_command(prepared, params, algorithm, d, device, out, offset)
    command.launch()
    return force


def force_command(prepared: PreparedLines, params: Params, algorithm: str, d: float, device: str, out=None,
                  offset: float = 0.0):
    """The force launch of :func:`launch_force`, recorded (a ``wp.Launch``; run it with
    ``.launch()``), and the array it writes: the host work of a launch (the lift table, the
    arguments' packing; ~0.2 ms for the tree) is done here once, so that the scaling study
    can time the kernel alone. Keep ``prepared`` alive while the command may run: it owns the
    memory behind its prefix-sum rows (``prefix_owner``)."""
    from ..kernels.common import BLOCK
    from ..kernels.direct import contact_force_direct
    from ..kernels.edge import contact_force_edge
    from ..kernels.tree import contact_force_tree

    wp = warp()
    rows = prepared.lines.shape[0]
    force = out if out is not None else wp.empty((rows, prepared.steps), dtype=wp.float64, device=device)
    curvature = params.dx**2 / params.R
    p = prepared
    # direct and tree: one thread per BLOCK consecutive steps; edge: one per step
    dim = (rows, -(-p.steps // BLOCK))
    if algorithm in ("direct", "tree"):
        lifts, origin = lift_table(params, d, p.h_top, device)
    if algorithm == "direct":
        inputs = [p.lines, p.bounds, lifts, origin, p.n_work, p.first, p.steps, d, curvature, params.k_spring, offset,
                  force]
        kernel = contact_force_direct
    elif algorithm == "tree":
        inputs = [p.lines, p.prefix, p.tree, p.level_offsets, lifts, origin, p.top_level, p.leaf_size, p.band_limit,
                  p.n_work, p.first, p.steps, d, curvature, params.k_spring, offset, force]
        kernel = contact_force_tree
    else:
        inputs = [p.prefix, p.first, edge_geometry(params, d), offset, force]
        kernel = contact_force_edge
        dim = force.shape
    return wp.launch(kernel, dim=dim, inputs=inputs, device=device, record_cmd=True), force


def contact_force(
    lines,
    params: Params,
    algorithm: str = "tree",
    boundary: str = "open",
    d: float | None = None,
    device: str | None = None,
    *,
    leaf_size: int = DEFAULT_LEAF_SIZE,
    band_limit: int = DEFAULT_BAND_LIMIT,
    h_max: float | None = None,
):
    """Contact force F[r, s] (N) of each line r at each wheel step s, at constant indentation d.

    Parameters
    ----------
    lines : (R, n) or (n,) float64 array, metres
        Rough lines on the grid ``x_i = i dx`` with ``n = params.n_points`` (NumPy, Warp or CuPy).
    params : Params
    algorithm : {"tree", "direct", "edge"}
        ``direct``: the exact spring sum (eq 10-12) over the window of possible contact.
        ``tree``: the bounding-tree algorithm, equal to ``direct`` to rounding.
        ``edge``: the edge-incremental approximation of eq 49.
    boundary : {"open", "periodic"}
        ``open``: the thesis's line, wheel from near x_w = a to near L - a
        (:func:`step_range`); ``periodic``: the wheel visits every spring, indices wrap.
    d : float, optional
        Indentation (m); default ``params.d0`` (eq 14).
    device : str, optional
        Where to compute; default the device of ``lines``.
    leaf_size : int
        Springs per tree leaf (tree only).
    band_limit : int
        Tree only: in a line whose band of possible contact (root bounds, one side) holds at
        most this many springs the bands are summed directly, in wider ones by a traversal
        shared by 8 steps, O(log n) a step (a tuning knob; the result is the same to rounding).
    h_max : float, optional
        Height bound (m) that places the open-boundary wheel (default: max of ``lines``).

    Returns
    -------
    force : (R, S) float64, newtons
        NumPy for a NumPy input on the CPU, else a Warp array on the device. The wheel of step s
        is at ``x_w = (first + s) dx`` with ``first`` from :func:`step_range`.
    """
    wp = warp()
    check_choice("algorithm", algorithm, ALGORITHMS)
    check_choice("boundary", boundary, BOUNDARIES)
    if isinstance(leaf_size, bool) or not isinstance(leaf_size, (int, np.integer)) or leaf_size < 1:
        raise ParameterError(f"leaf_size = {leaf_size!r} is not allowed: it must be a positive integer")
    if isinstance(band_limit, bool) or not isinstance(band_limit, (int, np.integer)) or band_limit < 0:
        raise ParameterError(f"band_limit = {band_limit!r} is not allowed: it must be an integer >= 0 (springs)")
    d = params.d0 if d is None else d
    if isinstance(d, bool) or not isinstance(d, (int, float, np.floating, np.integer)) or not (math.isfinite(d) and d > 0):
        raise ParameterError(f"d = {d!r} is not allowed: the indentation must be positive and finite (m)")
    device = resolve_device(device if device is not None else device_of(lines) or "cpu")
    host_input = isinstance(lines, np.ndarray)
    if not isinstance(lines, wp.array) and np.dtype(getattr(lines, "dtype", np.float64)) != np.float64:
        raise ParameterError(f"lines must be float64 (the force path is float64 throughout), got {lines.dtype}")
    one_line = getattr(lines, "ndim", 2) == 1
    data = to_warp(np.atleast_2d(lines) if host_input else lines, device)
    if one_line:
        data = data.reshape((1, data.shape[0]))
    if data.ndim != 2 or data.shape[1] != params.n_points:
        raise ParameterError(
            f"lines has shape {tuple(data.shape)}; expected (R, {params.n_points}) for L = {params.L!r} m, dx = {params.dx!r} m"
        )
    if data.dtype != wp.float64:
        raise ParameterError(f"lines must be float64 (the force path is float64 throughout), got {data.dtype}")
    prepared = prepare_lines(data, params, algorithm, boundary, float(d), device, int(leaf_size), h_max, int(band_limit))
    force = launch_force(prepared, params, algorithm, float(d), device)
    if host_input and device == "cpu":
        out = force.numpy()
        return out[0] if one_line else out
    return force
