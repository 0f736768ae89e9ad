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
gets its own, narrower core (closed form per step) and window. A narrow band (at most
``band_limit`` springs) is summed by the same register-blocked loop as the direct sum; a wide
one, as under refinement, where the band grows as 1/dx, is traversed once for the 8 steps
together (``band_descent``), which keeps the work per step near O(log n). Threads whose
springs are not all on the line (the ends of an open line) take the per-step traversal. All
paths are exact.

Stack bound: a band starts with at most 2 nodes on the stack, and each descent pops one node and
pushes two, so the stack never holds more than ``2 + start level <= 2 + top level`` entries; the
launcher checks ``2 + top level <= TREE_STACK_CAPACITY`` before launch.
"""

import warp as wp

from .common import (
    BLOCK,
    block_values,
    blocked_spring_sum,
    full_contact_sum,
    reach_inclusive,
    reach_strict,
    spring_sum,
    sum_of_offsets,
    sum_of_squares,
    tree_stack,
)

#: One bit per step of a thread's 8 (band_descent's step masks).
ALL_STEPS = wp.constant(255)
#: Nodes are pushed as ``(index << LEVEL_BITS) | level`` (levels < 32).
LEVEL_BITS = wp.constant(5)
LEVEL_MASK = wp.constant(31)


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
    """Add ``sum_{l=lo}^{hi} max(h_l + d - curvature (l - c - j)^2, 0)`` (m) to ``acc[j]`` for the
    8 steps j = 0..7 (wheel at spring c + j) by one tree traversal shared by the 8 steps.

    Each node is classified for every step as in :func:`band_sum`; a node that is full or empty
    for all steps ends there (full steps by the closed form, whose sums of squares for the 8
    shifted centres follow from one ``sum m^2`` and one ``sum m``:
    ``sum (m - j)^2 = sum m^2 - 2 j sum m + j^2 count``, exact integers); a node ambiguous for
    some step is split, and at a leaf its springs are summed for the ambiguous steps. The
    springs a warp's threads visit stay few however fine dx is, unlike a direct sum of the band.

    Requires that no wheel c .. c+7 lies in lo..hi (the caller's bands start past the core).
    """
    if lo > hi:
        return acc
    stack, top = band_roots(lo, hi, leaf_size, top_level)
    zero = wp.float64(0.0)
    while top > 0:
        top -= 1
        level, index, i, j = node_span(stack[top], leaf_size, lo, hi)
        if i < j:
            box = tree[r, level_offsets[level] + index]
            # no wheel lies on the node, so over the node and the 8 steps the distance to the
            # wheel is extreme at the ends: two tests settle "full for all" and "empty for all"
            near = wp.min(wp.min(wp.abs(i - c), wp.abs(i - c - BLOCK + 1)),
                          wp.min(wp.abs(j - 1 - c), wp.abs(j - c - BLOCK)))
            far = wp.max(wp.max(wp.abs(i - c), wp.abs(i - c - BLOCK + 1)),
                         wp.max(wp.abs(j - 1 - c), wp.abs(j - c - BLOCK)))
            f_near = wp.float64(near)
            f_far = wp.float64(far)
            full = int(0)
            ambiguous = int(0)
            if curvature * f_far * f_far - d < box[0]:
                full = ALL_STEPS
            elif curvature * f_near * f_near - d <= box[1]:
                ambiguous = ALL_STEPS
                if level == 0:
                    # a leaf: classify each step, as band_sum does for one
                    ambiguous = int(0)
                    p = wp.float64(i - c)
                    q = wp.float64(j - 1 - c)
                    for k in range(BLOCK):
                        g_p = curvature * p * p - d
                        g_q = curvature * q * q - d
                        if wp.max(g_p, g_q) < box[0]:
                            full = full | (1 << k)
                        elif wp.min(g_p, g_q) <= box[1]:
                            ambiguous = ambiguous | (1 << k)
                        p -= wp.float64(1.0)
                        q -= wp.float64(1.0)
            if ambiguous != 0 and level > 0:
                stack[top] = ((2 * index) << LEVEL_BITS) | (level - 1)
                stack[top + 1] = ((2 * index + 1) << LEVEL_BITS) | (level - 1)
                top += 2
            else:
                if full != 0:
                    springs = wp.float64(j - i)
                    base = (prefix[r, j] - prefix[r, i]) + springs * d
                    square_sum = sum_of_squares(i - c, j - 1 - c)
                    offset_sum = sum_of_offsets(i - c, j - 1 - c)
                    shift = wp.float64(0.0)  # k as a float; wp.float64(k) would retype the unrolled k (Warp 1.19)
                    for k in range(BLOCK):
                        term = base - curvature * (square_sum - wp.float64(2.0) * shift * offset_sum + shift * shift * springs)
                        if ((full >> k) & 1) == 1:
                            acc[k] = acc[k] + term
                        shift += wp.float64(1.0)
                if ambiguous != 0:
                    for l in range(i, j):
                        h_l = h[r, l] + d
                        m = wp.float64(l - c)
                        for k in range(BLOCK):
                            if ((ambiguous >> k) & 1) == 1:
                                acc[k] = acc[k] + wp.max(h_l - curvature * m * m, zero)
                            m -= wp.float64(1.0)
    return acc


@wp.kernel
def contact_force_tree(
    h: wp.array2d(dtype=wp.float64),
    prefix: wp.array2d(dtype=wp.float64),
    tree: wp.array2d(dtype=wp.vec2d),
    level_offsets: wp.array(dtype=int),
    lifts: wp.array(dtype=wp.float64),
    lift_origin: int,
    top_level: int,
    leaf_size: int,
    band_limit: int,
    n: int,
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

    Launched over ``(R, ceil(steps / 8))``; thread t computes steps 8t .. 8t+7. Bands of at
    most ``band_limit`` springs are summed directly (register-blocked), wider ones descend the
    tree (:func:`band_descent`).
    """
    r, t = wp.tid()
    base = t * BLOCK
    c = first + base
    root = tree[r, level_offsets[top_level]]
    outer = reach_inclusive(d + root[1], curvature)
    core = reach_strict(d + root[0], curvature)
    if core >= 0 and base + BLOCK <= steps and c - outer - BLOCK >= 0 and c + outer + 3 * BLOCK < n:
        # local bounds over the springs the 8 steps' bands can reach, right and left
        right = range_bounds(tree, level_offsets, leaf_size, r, c + core + 1, c + BLOCK - 1 + outer)
        left = range_bounds(tree, level_offsets, leaf_size, r, c - outer, c + BLOCK - 1 - core - 1)
        core_right = wp.max(core, reach_strict(d + right[0], curvature))
        outer_right = wp.min(outer, reach_inclusive(d + right[1], curvature))
        core_left = wp.max(core, reach_strict(d + left[0], curvature))
        outer_left = wp.min(outer, reach_inclusive(d + left[1], curvature))
        # a side whose band holds more than band_limit springs is traversed once for the 8
        # steps (band_descent); its core edge is then shared by the 8 steps
        descend_right = outer_right - core_right > band_limit and core_right >= BLOCK - 1
        descend_left = outer_left - core_left > band_limit and core_left >= BLOCK - 1
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
