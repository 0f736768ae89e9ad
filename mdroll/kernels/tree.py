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

Stack bound: a band starts with at most 2 nodes on the stack, and each descent pops one node and
pushes two, so the stack never holds more than ``2 + start level <= 2 + top level`` entries; the
launcher checks ``2 + top level <= TREE_STACK_CAPACITY`` before launch.
"""

import warp as wp

from .common import (
    full_contact_sum,
    reach_inclusive,
    reach_strict,
    spring_sum,
    tree_stack,
)

#: Nodes are pushed as ``(index << LEVEL_BITS) | level`` (levels < 32).
LEVEL_BITS = wp.constant(5)
LEVEL_MASK = wp.constant(31)


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
    while top > 0:
        top -= 1
        code = stack[top]
        level = code & LEVEL_MASK
        index = code >> LEVEL_BITS
        size = leaf_size << level
        i = wp.max(index * size, lo)
        j = wp.min(index * size + size, hi + 1)
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
                        acc += spring_sum(h, r, i, j, c, d, curvature)
                    else:
                        stack[top] = ((2 * index) << LEVEL_BITS) | (level - 1)
                        stack[top + 1] = ((2 * index + 1) << LEVEL_BITS) | (level - 1)
                        top += 2
    return acc


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
) -> wp.float64:
    """Sum of positive spring displacements (m), wheel at spring c, indentation d (m)."""
    root = tree[r, level_offsets[top_level]]
    outer = reach_inclusive(d + root[1], curvature)
    if outer < 0:
        return wp.float64(0.0)
    core = reach_strict(d + root[0], curvature)  # -1: no certain core, the right band then starts at c
    acc = full_contact_sum(prefix, r, wp.max(c - core, 0), wp.min(c + core + 1, n), c, d, curvature)
    acc += band_sum(
        h, prefix, tree, level_offsets, top_level, leaf_size, r, c,
        wp.max(c + core + 1, 0), wp.min(c + outer, n - 1), d, curvature,
    )
    acc += band_sum(
        h, prefix, tree, level_offsets, top_level, leaf_size, r, c,
        wp.max(c - outer, 0), wp.min(c - wp.max(core, 0) - 1, n - 1), d, curvature,
    )
    return acc


@wp.kernel
def contact_force_tree(
    h: wp.array2d(dtype=wp.float64),
    prefix: wp.array2d(dtype=wp.float64),
    tree: wp.array2d(dtype=wp.vec2d),
    level_offsets: wp.array(dtype=int),
    top_level: int,
    leaf_size: int,
    n: int,
    first: int,
    d: wp.float64,
    curvature: wp.float64,
    k_spring: wp.float64,
    force: wp.array2d(dtype=wp.float64),
):
    """``force[r, s]`` (N): wheel at spring ``first + s`` of row r, indentation d (m)."""
    r, s = wp.tid()
    force[r, s] = k_spring * force_tree(
        h, prefix, tree, level_offsets, top_level, leaf_size, r, n, first + s, d, curvature
    )
