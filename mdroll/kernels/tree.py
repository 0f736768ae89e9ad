"""Bounding tree, O(n log n) (physics.md section 4), exact to floating-point rounding.

Per line, precomputed once: the prefix sums ``S_j`` (eq 18) and an implicit binary tree of
(min h, max h). Level 0 holds leaves of ``leaf_size`` springs; a node of level L covers
``leaf_size * 2^L`` springs; the top level is a single root. ``level_offsets[L]`` is where level L
starts in the flat per-row node array.

Per step, the root bounds already split the contact (physics.md section 4): springs with
``curvature m^2 < d + min h`` touch whatever h is (the *core*, one closed form), springs with
``curvature m^2 > d + max h`` never touch, and only the two bands in between are ambiguous. Each
band is covered by at most two nodes of the smallest level whose nodes are at least as wide as
the band; from there an explicit-stack depth-first traversal classifies every node, clipped to
the band, as

- *full contact* (indenter below the node's min h at both ends; the indenter is convex):
  exact closed form ``full_contact_sum`` (discrete eq 19-20, offsets relative to the wheel);
- *no contact* (indenter above the node's max h everywhere on the node): nothing;
- *ambiguous*: split into the two children, or summed spring by spring at a leaf.

On the GPU the per-step traversal diverges across a warp, so the kernel's main path works on 8
consecutive steps per thread instead: two range queries on the tree give (min h, max h) over
the springs that the 8 steps' right and left bands can reach; from those local bounds each side
gets its own, narrower core (closed form per step) and window. In a row whose band (root
bounds: window less certain core, one side) holds at most ``band_limit`` springs, the narrowed
bands are summed by the same register-blocked loop as the direct sum; in a wider one, as under
refinement, where the band grows as 1/dx, each is traversed once for the 8 steps together
(``band_descent``), which keeps the work per step near O(log n). The choice is per row, so the
threads of a warp take the same path. Threads whose springs are not all on the line (the ends
of an open line) take the per-step traversal. All paths are exact.

The main kernel is compiled for at most ``TREE_MAX_REGISTERS`` registers a thread: left free,
the compiler took 255, which leaves 8 warps a streaming multiprocessor.

Stack bound: a band starts with at most 2 nodes on the stack, and each descent pops one node and
pushes two, so the stack never holds more than ``2 + start level <= 2 + top level`` entries; the
launcher checks ``2 + top level`` against the stack's length (``common.tree_stack``) before launch.
"""

import warp as wp

from .common import (
    BLOCK,
    BLOCK_HEIGHTS,
    Contact,
    block_heights,
    block_values,
    blocked_last_read,
    blocked_spring_sum,
    full_contact_sum,
    reach_inclusive,
    reach_strict,
    spring_sum,
    sum_of_offsets,
    sum_of_squares,
    tree_stack,
)
from .dynamics import coupled_dynamics
from .sweep_coupled import BandRow, band_row, lane_band_force, prefetch_ahead, settled_reaches

#: Nodes are pushed as ``(index << LEVEL_BITS) | level`` (levels < 2^LEVEL_BITS = 32).
LEVEL_BITS = wp.constant(5)
LEVEL_MASK = wp.constant((1 << LEVEL_BITS) - 1)
#: Register cap of the main kernel: 128 lets 16 warps share a streaming multiprocessor, the
#: fastest of the caps compared (docs/performance.md, "Tree").
TREE_MAX_REGISTERS = 128
#: A lifted height (m) below every indenter depth: a masked spring's displacement is negative.
NO_CONTACT = wp.constant(wp.float64(-1.0e300))


@wp.struct
class TreeLines:
    """What the tree kernels read of a batch of lines (rows of ``n`` springs): heights ``h`` (m),
    prefix sums ``prefix`` (m; eq 18, (R, n + 1)), the implicit min/max tree ``nodes`` (m; level
    L starts at ``level_offsets[L]``, the root alone on ``top_level``), ``leaf_size`` springs a
    leaf, and ``band_limit``: the band width (springs a side) above which the main path
    descends the tree instead of summing the bands directly."""

    h: wp.array2d(dtype=wp.float64)
    prefix: wp.array2d(dtype=wp.float64)
    nodes: wp.array2d(dtype=wp.vec2d)
    level_offsets: wp.array(dtype=int)
    top_level: int
    leaf_size: int
    band_limit: int
    n: int


@wp.func
def band_roots(lo: int, hi: int, leaf_size: int, top_level: int) -> tuple[tree_stack, int]:
    """The traversal's start for the band ``lo..hi`` (lo <= hi): a stack holding the (at most 2)
    nodes of the smallest level whose nodes are at least as wide as the band, and its depth."""
    level = int(0)
    size = leaf_size
    while size < hi - lo + 1 and level < top_level:
        level += 1
        size *= 2
    stack = tree_stack()
    top = int(0)
    for first_node in range(lo // size, hi // size + 1):
        stack[top] = (first_node << LEVEL_BITS) | level
        top += 1
    return stack, top


@wp.func
def node_span(code: int, leaf_size: int, lo: int, hi: int) -> tuple[int, int, int, int]:
    """A pushed node's level and index, and the springs ``i..j-1`` it covers, clipped to ``lo..hi``
    (``i >= j``: none)."""
    level = code & LEVEL_MASK
    index = code >> LEVEL_BITS
    size = leaf_size << level
    return level, index, wp.max(index * size, lo), wp.min(index * size + size, hi + 1)


@wp.func
def band_sum(
    h: wp.array2d(dtype=wp.float64),
    prefix: wp.array2d(dtype=wp.float64),
    tree: wp.array2d(dtype=wp.vec2d),
    level_offsets: wp.array(dtype=int),
    top_level: int,
    leaf_size: int,
    r: int,
    c: int,
    lo: int,
    hi: int,
    d: wp.float64,
    curvature: wp.float64,
) -> wp.float64:
    """Exact ``sum_{l=lo}^{hi} max(h_l + d - curvature (l - c)^2, 0)`` (m) by tree traversal."""
    acc = wp.float64(0.0)
    if lo > hi:
        return acc
    stack, top = band_roots(lo, hi, leaf_size, top_level)
    while top > 0:
        top -= 1
        level, index, i, j = node_span(stack[top], leaf_size, lo, hi)
        if i < j:
            box = tree[r, level_offsets[level] + index]
            p = wp.float64(i - c)
            q = wp.float64(j - 1 - c)
            g_p = curvature * p * p - d
            g_q = curvature * q * q - d
            if wp.max(g_p, g_q) < box[0]:
                acc += full_contact_sum(prefix, r, i, j, c, d, curvature)
            else:
                g_low = wp.min(g_p, g_q)
                if i <= c and c < j:
                    g_low = -d  # the indenter's lowest point lies inside the node
                if g_low <= box[1]:
                    if level == 0:
                        acc += spring_sum(h, r, i, j, 1, c, d, curvature)
                    else:
                        stack[top] = ((2 * index) << LEVEL_BITS) | (level - 1)
                        stack[top + 1] = ((2 * index + 1) << LEVEL_BITS) | (level - 1)
                        top += 2
    return acc


@wp.func
def lane_slice_start(lo: int, hi: int, lane: int, lanes: int) -> int:
    """First spring of lane's contiguous share of ``lo..hi`` split among ``lanes`` lanes."""
    return lo + (lane * wp.max(hi - lo + 1, 0)) // lanes


@wp.func
def force_tree(
    h: wp.array2d(dtype=wp.float64),
    prefix: wp.array2d(dtype=wp.float64),
    tree: wp.array2d(dtype=wp.vec2d),
    level_offsets: wp.array(dtype=int),
    top_level: int,
    leaf_size: int,
    r: int,
    n: int,
    c: int,
    d: wp.float64,
    curvature: wp.float64,
    lane: int,
    lanes: int,
) -> wp.float64:
    """Sum of positive spring displacements (m), wheel at spring c, indentation d (m).

    Shared by the ``lanes`` threads of a block: lane 0 adds the core, and each lane traverses
    its contiguous share of each band (the whole sum for ``lane = 0, lanes = 1``).
    """
    root = tree[r, level_offsets[top_level]]
    outer = reach_inclusive(d + root[1], curvature)
    if outer < 0:
        return wp.float64(0.0)
    core = reach_strict(d + root[0], curvature)  # -1: no certain core, the right band then starts at c
    acc = wp.float64(0.0)
    if lane == 0:
        acc = full_contact_sum(prefix, r, wp.max(c - core, 0), wp.min(c + core + 1, n), c, d, curvature)
    lo = wp.max(c + core + 1, 0)
    hi = wp.min(c + outer, n - 1)
    acc += band_sum(
        h, prefix, tree, level_offsets, top_level, leaf_size, r, c,
        lane_slice_start(lo, hi, lane, lanes), lane_slice_start(lo, hi, lane + 1, lanes) - 1, d, curvature,
    )
    lo = wp.max(c - outer, 0)
    hi = wp.min(c - wp.max(core, 0) - 1, n - 1)
    acc += band_sum(
        h, prefix, tree, level_offsets, top_level, leaf_size, r, c,
        lane_slice_start(lo, hi, lane, lanes), lane_slice_start(lo, hi, lane + 1, lanes) - 1, d, curvature,
    )
    return acc


@wp.func
def range_bounds(
    tree: wp.array2d(dtype=wp.vec2d),
    level_offsets: wp.array(dtype=int),
    leaf_size: int,
    r: int,
    lo: int,
    hi: int,
) -> wp.vec2d:
    """(min h, max h) valid for springs lo..hi: exact over the whole leaves that cover them.

    The iterative segment-tree query: at most two nodes per level.
    """
    a = lo // leaf_size
    b = hi // leaf_size
    box = tree[r, a]
    low = box[0]
    high = box[1]
    level = int(0)
    while a <= b:
        if (a & 1) == 1:
            node = tree[r, level_offsets[level] + a]
            low = wp.min(low, node[0])
            high = wp.max(high, node[1])
            a += 1
        if (b & 1) == 0:
            node = tree[r, level_offsets[level] + b]
            low = wp.min(low, node[0])
            high = wp.max(high, node[1])
            b -= 1
        a = a >> 1
        b = b >> 1
        level += 1
    return wp.vec2d(low, high)


@wp.func
def span_totals(prefix: wp.array2d(dtype=wp.float64), r: int, i: int, j: int, c: int) -> wp.vec4d:
    """Over springs ``l = i .. j-1`` of row r: (count, sum h (m), sum m, sum m^2) with offsets
    ``m = l - c`` from the wheel; the count and the offset sums are exact integers (eq 18-20)."""
    return wp.vec4d(wp.float64(j - i), prefix[r, j] - prefix[r, i], sum_of_offsets(i - c, j - 1 - c),
                    sum_of_squares(i - c, j - 1 - c))


@wp.func
def indenter_depths(m0: int, curvature: wp.float64) -> block_heights:
    """``curvature m^2`` (m) for the 15 offsets ``m = m0 .. m0 + 14``: the indenter depths that the
    64 (spring, step) pairs of a block of 8 springs and 8 steps need (eq 7)."""
    depth = block_heights()
    m = wp.float64(m0)
    for t in range(BLOCK_HEIGHTS):
        depth[t] = curvature * m * m
        m += wp.float64(1.0)
    return depth


@wp.func
def next_node(index: int, level: int, size: int, top_level: int, hi: int) -> tuple[int, int, int]:
    """The node after ``(index, level)`` (``size`` springs) in a left-to-right walk of a band that
    ends at spring hi: the right neighbour, lifted to its largest ancestor that starts at the same
    spring and still ends within the band. Returns (index, level, size)."""
    next_index = index + 1
    next_level = level
    next_size = size
    while (next_index & 1) == 0 and next_level < top_level and (next_index + 2) * next_size <= hi + 1:
        next_index = next_index >> 1
        next_level += 1
        next_size *= 2
    return next_index, next_level, next_size


@wp.func
def band_descent(
    h: wp.array2d(dtype=wp.float64),
    prefix: wp.array2d(dtype=wp.float64),
    tree: wp.array2d(dtype=wp.vec2d),
    level_offsets: wp.array(dtype=int),
    top_level: int,
    leaf_size: int,
    r: int,
    c: int,
    lo: int,
    hi: int,
    d: wp.float64,
    curvature: wp.float64,
    acc: block_values,
) -> block_values:
    """Add ``sum_{l=lo}^{hi} max(h_l + d - curvature (l - c - k)^2, 0)`` (m) to ``acc[k]`` for the
    8 steps k = 0..7 (wheel at spring c + k) by one tree walk shared by the 8 steps.

    The walk goes left to right without a stack: at each node (clipped to the band) two tests
    settle "in contact for all 8 steps" and "out of contact for all"; a node that is neither is
    replaced by its left child, a settled one by its right neighbour lifted to the largest
    ancestor that starts there (:func:`next_node`). Settled-full nodes only add to four running
    totals, the spring count and the sums of h, m and m^2 (m = l - c), and the 8 closed forms
    follow once at the end: ``sum (m - k)^2 = sum m^2 - 2 k sum m + k^2 count`` (eq 19-20, exact
    integers). A run of adjacent leaves that stay mixed is summed for the 8 steps in blocks of 8
    springs (eq 10-12): whole blocks by ``max(u, 0) = (u + |u|) / 2``, their ``sum u`` in the
    same totals, the last partial block by ``max(u, 0)``.

    On the GPU the runs' sums are the costly part, and a thread reaches its mixed leaves at its
    own pace: the walk to the end of the next run is an inner loop, and the sum follows it in
    the outer one, so a warp's threads sum their runs together instead of each stalling the rest.
    The nodes visited grow as the number of contact edges in the band times its depth, not as
    the band's width.

    Requires that no wheel c .. c+7 lies in lo..hi (the caller's bands start past the core).
    """
    if lo > hi:
        return acc
    one = wp.float64(1.0)
    two = wp.float64(2.0)
    zero = wp.float64(0.0)
    # span_totals weighted 2 for settled-full nodes and 1 for the whole blocks of mixed runs,
    # which add sum |u| per step to ``absolute``
    totals = wp.vec4d()
    absolute = block_values()
    index = lo // leaf_size
    level = int(0)
    size = leaf_size
    while index * size <= hi:
        # walk to the next run of adjacent mixed leaves (or past the band)
        run_start = int(-1)
        run_end = int(-1)
        walking = int(1)
        while walking == 1 and index * size <= hi:
            i = wp.max(index * size, lo)
            j = wp.min(index * size + size, hi + 1)
            settled = int(1)
            if i < j:
                box = tree[r, level_offsets[level] + index]
                # no wheel lies on the node, so over the node and the 8 steps the distance to
                # the wheel is extreme at the ends
                near = wp.min(wp.min(wp.abs(i - c), wp.abs(i - c - BLOCK + 1)),
                              wp.min(wp.abs(j - 1 - c), wp.abs(j - c - BLOCK)))
                far = wp.max(wp.max(wp.abs(i - c), wp.abs(i - c - BLOCK + 1)),
                             wp.max(wp.abs(j - 1 - c), wp.abs(j - c - BLOCK)))
                f_near = wp.float64(near)
                f_far = wp.float64(far)
                if curvature * f_far * f_far - d < box[0]:
                    totals = totals + two * span_totals(prefix, r, i, j, c)
                elif curvature * f_near * f_near - d <= box[1]:
                    settled = 0
            if settled == 0 and level > 0:
                index = 2 * index
                level -= 1
                size = size >> 1
            else:
                if settled == 0:
                    if run_end < 0:
                        run_start = i
                    run_end = j
                elif run_end >= 0:
                    walking = 0
                index, level, size = next_node(index, level, size, top_level, hi)
        if run_end >= 0:
            # whole blocks of 8 springs by max(u, 0) = (u + |u|) / 2, sum u in the totals; the
            # last, partial block by max(u, 0) with the missing springs out of reach
            whole_end = run_start + ((run_end - run_start) // BLOCK) * BLOCK
            totals = totals + span_totals(prefix, r, run_start, whole_end, c)
            for first in range(run_start, run_end, BLOCK):
                lifted = block_values()
                for q in range(BLOCK):
                    lifted[q] = NO_CONTACT
                    if first + q < run_end:
                        lifted[q] = h[r, first + q] + d
                depth = indenter_depths(first - c - BLOCK + 1, curvature)
                if first < whole_end:
                    for q in range(BLOCK):
                        for k in range(BLOCK):
                            absolute[k] = absolute[k] + wp.abs(lifted[q] - depth[q - k + BLOCK - 1])
                else:
                    for q in range(BLOCK):
                        for k in range(BLOCK):
                            acc[k] = acc[k] + wp.max(lifted[q] - depth[q - k + BLOCK - 1], zero)
    shift = wp.float64(0.0)  # k as a float; wp.float64(k) would retype the unrolled k (Warp 1.19)
    half = wp.float64(0.5)
    for k in range(BLOCK):
        signed = totals[1] + totals[0] * d - curvature * (totals[3] - two * shift * totals[2] + shift * shift * totals[0])
        acc[k] = acc[k] + half * (signed + absolute[k])
        shift += one
    return acc


@wp.kernel(cuda_max_registers=TREE_MAX_REGISTERS)
def contact_force_tree(
    lines: TreeLines,
    lifts: wp.array(dtype=wp.float64),
    lift_origin: int,
    first: int,
    steps: int,
    d: wp.float64,
    curvature: wp.float64,
    k_spring: wp.float64,
    offset: wp.float64,
    force: wp.array2d(dtype=wp.float64),
):
    """``force[r, s] = F - offset`` (N): F with the wheel at spring ``first + s`` of row r,
    indentation d (m).

    Launched over ``(R, ceil(steps / 8))``; thread t computes steps 8t .. 8t+7. In rows whose
    band holds at most ``band_limit`` springs a side the bands are summed directly
    (register-blocked), in wider ones they descend the tree (:func:`band_descent`).
    """
    h = lines.h
    prefix = lines.prefix
    tree = lines.nodes
    level_offsets = lines.level_offsets
    top_level = lines.top_level
    leaf_size = lines.leaf_size
    n = lines.n
    r, t = wp.tid()
    base = t * BLOCK
    c = first + base
    root = tree[r, level_offsets[top_level]]
    outer = reach_inclusive(d + root[1], curvature)
    core = reach_strict(d + root[0], curvature)
    # every spring the main path reads lies on the line: its blocked sums read from a left
    # band's first block (offset >= -outer - (BLOCK - 1)) to a right band's last block (which
    # starts at most at offset outer), its descents and range queries within c - outer ..
    # c + BLOCK - 1 + outer
    if (core >= 0 and base + BLOCK <= steps and c - outer - (BLOCK - 1) >= 0
            and c + blocked_last_read(outer, 1) < n):
        # local bounds over the springs the 8 steps' bands can reach, right and left
        right = range_bounds(tree, level_offsets, leaf_size, r, c + core + 1, c + BLOCK - 1 + outer)
        left = range_bounds(tree, level_offsets, leaf_size, r, c - outer, c + BLOCK - 1 - core - 1)
        core_right = wp.max(core, reach_strict(d + right[0], curvature))
        outer_right = wp.min(outer, reach_inclusive(d + right[1], curvature))
        core_left = wp.max(core, reach_strict(d + left[0], curvature))
        outer_left = wp.min(outer, reach_inclusive(d + left[1], curvature))
        # in a row whose band is wider than band_limit each side is traversed once for the 8
        # steps (band_descent); its core edge is then shared by the 8 steps
        wide = outer - core > lines.band_limit
        descend_right = wide and core_right >= BLOCK - 1
        descend_left = wide and core_left >= BLOCK - 1
        acc = block_values()
        for j in range(BLOCK):
            low = c + j - core_left
            if descend_left:
                low = c + BLOCK - 1 - core_left
            high = c + j + core_right
            if descend_right:
                high = c + core_right
            acc[j] = full_contact_sum(prefix, r, low, high + 1, c + j, d, curvature)
        # blocked bands are padded on their outer side only: padded offsets lie beyond the local
        # window (or beyond the global one), where u < 0 exactly
        row = h[r]
        if descend_right:
            acc = band_descent(h, prefix, tree, level_offsets, top_level, leaf_size, r, c,
                               c + core_right + 1, c + BLOCK - 1 + outer_right, d, curvature, acc)
        else:
            right_blocks = (outer_right - core_right + BLOCK - 1) // BLOCK
            acc = blocked_spring_sum(row, c, core_right + 1, right_blocks, lifts, lift_origin, d, curvature, acc)
        if descend_left:
            acc = band_descent(h, prefix, tree, level_offsets, top_level, leaf_size, r, c,
                               c - outer_left, c + BLOCK - 1 - core_left - 1, d, curvature, acc)
        else:
            left_blocks = (outer_left - core_left + BLOCK - 1) // BLOCK
            acc = blocked_spring_sum(row, c, -core_left - left_blocks * BLOCK, left_blocks, lifts, lift_origin, d,
                                     curvature, acc)
        for j in range(BLOCK):
            force[r, base + j] = k_spring * acc[j] - offset
    else:
        for j in range(BLOCK):
            s = base + j
            if s < steps:
                force[r, s] = k_spring * force_tree(
                    h, prefix, tree, level_offsets, top_level, leaf_size, r, n, first + s, d, curvature, 0, 1
                ) - offset


@wp.func
def tree_row(lines: TreeLines, r: int, contact: Contact) -> BandRow:
    """The tree's row set-up for the coupled dynamics: the row with its root bounds
    (:func:`~mdroll.kernels.sweep_coupled.band_row`)."""
    return band_row(lines.h, lines.prefix, r, lines.n, lines.nodes[r, lines.level_offsets[lines.top_level]])


@wp.func
def tree_lane_force(lines: TreeLines, row: BandRow, c: int, d: wp.float64, contact: Contact, lane: int, lanes: int):
    """This lane's part (N) of F (eq 11-12) with the wheel at spring c of the row, indentation d
    (m), and the row with this step's reaches. As the main kernel, by the band's width from the
    root bounds (last step's, the choice being one of speed only): up to ``band_limit`` springs
    a side, the core in closed form and the bands spring by spring (:func:`lane_band_force`, the
    sweep's coupled step, its springs prefetched); wider, lane 0 the core and each lane its
    slice of the bands by traversal (:func:`force_tree`)."""
    prefetch_ahead(row, c, lane)
    if row.outer - wp.max(row.core, 0) <= lines.band_limit:
        return lane_band_force(row, c, d, contact, lane, lanes)
    settled = settled_reaches(row, d, contact.curvature)
    return contact.k_spring * force_tree(lines.h, lines.prefix, lines.nodes, lines.level_offsets, lines.top_level,
                                         lines.leaf_size, row.r, lines.n, c, d, contact.curvature, lane,
                                         lanes), settled


#: Eq 13 with the tree (:func:`mdroll.kernels.dynamics.coupled_dynamics`).
coupled_tree = coupled_dynamics(TreeLines, tree_lane_force, tree_row)
