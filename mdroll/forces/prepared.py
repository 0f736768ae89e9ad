"""Lines prepared for the force kernels (physics.md section 4): :class:`PreparedLines` and the
passes that fill it, each run only for an algorithm that needs it (:mod:`mdroll.forces.prepare`):
the periodic copy, the row bounds, the prefix sums (eq 18) and the min/max tree."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import buffers
from ..devices import is_cuda, to_warp, warp
from ..kernels import common
from ..kernels.lines import (BOUNDS_GROUP, BOUNDS_THREADS, periodic_extend, row_min_max, segment_min_max,
                             strided_min_max, tree_parents)
from ..errors import ParameterError

#: Springs per tree leaf: the fastest leaf size at thesis scale (docs/performance.md, "Tree").
DEFAULT_LEAF_SIZE = 32
#: Band width (springs a side, from a row's root bounds) above which the tree kernel's main path
#: descends the tree instead of summing the narrowed bands directly (kernels/tree.py): the direct
#: sum is faster up to bands of about this width (docs/performance.md, "Tree"); at thesis scale
#: (~40) the bands are always summed directly.
DEFAULT_BAND_LIMIT = 2048


@dataclass
class PreparedLines:
    """Lines on a device with everything the force kernels read.

    ``lines`` is what the kernels index: the input itself (open) or a copy with ``first``
    wrapped springs on each side (periodic). The wheel of step s sits at spring ``first + s``
    of ``lines``. ``bounds[r] = (min h, max h)`` of row r (None where the algorithm needs no
    bounds and h_max is given); ``prefix`` (R, n_work + 1) holds ``S_j = sum_{i<j} h_i``
    (eq 18) up to a constant per row; ``tree`` the implicit min/max tree. Each is None where the
    algorithm's registry entry does not need it (``needs``, :mod:`mdroll.forces.algorithm`).
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
    prefix_owner: object = None  # the flat array behind ``prefix`` (:func:`prefix_sums`)


def batch_bounds(bounds) -> tuple[float, float]:
    """The lowest and the largest height (m) of a batch from its row bounds (one host copy)."""
    host = bounds.numpy()
    return float(host[:, 0].min()), float(host[:, 1].max())


def row_bounds(lines, device, threads: int | None = None):
    """``(min h, max h)`` of each row, a (R,) ``vec2d`` array: ``threads`` a row (default
    BOUNDS_THREADS on CUDA, 1 on the CPU, where Warp runs a launch's threads one after another)
    take strided partials, combined in groups of BOUNDS_GROUP where they divide evenly, then per
    row."""
    wp = warp()
    rows, n = lines.shape
    if threads is None:
        threads = min(BOUNDS_THREADS, n) if is_cuda(device) else 1
    partial = wp.empty((rows, threads), dtype=wp.vec2d, device=device)
    bounds = wp.empty(rows, dtype=wp.vec2d, device=device)
    wp.launch(strided_min_max, dim=(rows, threads), inputs=[lines, n, threads, partial], device=device)
    if threads > BOUNDS_GROUP and threads % BOUNDS_GROUP == 0:
        # the partials in groups first: one thread combining a row's BOUNDS_THREADS partials
        # would wait on its loads
        groups = threads // BOUNDS_GROUP
        grouped = wp.empty(rows * groups, dtype=wp.vec2d, device=device)
        wp.launch(row_min_max, dim=rows * groups, inputs=[partial.reshape((rows * groups, BOUNDS_GROUP)), BOUNDS_GROUP,
                                                          grouped], device=device)
        partial, threads = grouped.reshape((rows, groups)), groups
    wp.launch(row_min_max, dim=rows, inputs=[partial, threads, bounds], device=device)
    return bounds


def prefix_sums(lines, device):
    """``S[r, j] - S[r, 0] = sum_{i<j} h[r, i]`` for j = 0..n (eq 18), as a (R, n + 1) Warp view,
    and the flat array that owns its memory.

    One inclusive scan over the whole batch laid end to end, out of place (Warp's
    ``array_scan``: CUB's device scan on CUDA, a sequential loop on the CPU), the fastest of the
    ways compared (docs/performance.md, "Prefix sums"). Row r is the view of the flat prefix from element r n, rows
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
    """``prepared.prefix`` (eq 18; see :func:`prefix_sums`), built on first use for a kernel
    that reads it where the algorithm's registry entry does not need it by default (the sweep's
    sequential form and its coupled step: its stream sums its anchors' cores spring by
    spring)."""
    if prepared.prefix is None:
        prepared.prefix, prepared.prefix_owner = prefix_sums(prepared.lines, device)
    return prepared.prefix


def tree_levels(n: int, leaf_size: int) -> list[int]:
    """Node counts per level of the implicit tree over n springs, leaves first, root last."""
    counts = [-(-n // leaf_size)]
    while counts[-1] > 1:
        counts.append(-(-counts[-1] // 2))
    return counts


def min_max_tree(lines, leaf_size: int, device):
    """The implicit (min h, max h) tree of each row (kernels/tree.py), its level offsets (device
    int32), its top level, and its root per row: the row bounds, as a (R,) ``vec2d`` array."""
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


def periodic_copy(lines, first: int, device):
    """A copy of ``lines`` with ``first`` wrapped springs on each side (the periodic boundary)."""
    wp = warp()
    rows, n = lines.shape
    work = buffers.empty("periodic lines", (rows, n + 2 * first), wp.float64, device)
    wp.launch(periodic_extend, dim=work.shape, inputs=[lines, n, first, work], device=device)
    return work
