"""Direct sum, O(n^2) under refinement (physics.md section 4): the exact reference.

Every spring within the window of possible contact ``|l - c| <= M``, ``curvature M^2 <= d + max h``,
contributes ``max(h_l + d - curvature (l - c)^2, 0)`` (eq 10-12); springs off the line
(``l < 0`` or ``l >= n``) do not exist.
"""

import warp as wp

from .common import BLOCK, Contact, block_values, blocked_last_read, blocked_spring_sum, reach_inclusive, spring_sum
from .dynamics import coupled_dynamics


@wp.struct
class DirectLines:
    """What the direct sum reads of a batch of lines: heights ``h`` (m, rows of ``n`` springs) and
    each row's ``bounds = (min h, max h)`` (m)."""

    h: wp.array2d(dtype=wp.float64)
    bounds: wp.array(dtype=wp.vec2d)
    n: int


@wp.func
def force_direct(
    h: wp.array2d(dtype=wp.float64),
    r: int,
    n: int,
    c: int,
    d: wp.float64,
    h_max: wp.float64,
    curvature: wp.float64,
    lane: int,
    lanes: int,
) -> wp.float64:
    """Sum of positive spring displacements (m) for the wheel at spring c, indentation d (m).

    Shared by the ``lanes`` threads of a block: this lane sums springs ``lane, lane + lanes, ...``
    of the window (the whole sum for ``lane = 0, lanes = 1``).
    """
    window = reach_inclusive(d + h_max, curvature)
    if window < 0:
        return wp.float64(0.0)
    return spring_sum(h, r, wp.max(c - window, 0) + lane, wp.min(c + window + 1, n), lanes, c, d, curvature)


@wp.kernel
def contact_force_direct(
    h: wp.array2d(dtype=wp.float64),
    bounds: wp.array(dtype=wp.vec2d),
    lifts: wp.array(dtype=wp.float64),
    lift_origin: int,
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
    indentation d (m); eq 11-12.

    Launched over ``(R, ceil(steps / 8))``; thread t computes steps 8t .. 8t+7. Offsets run in
    whole blocks of 8 from ``-window``; the few past ``+window`` add exactly nothing (there
    ``curvature m^2 > d + max h``, so u < 0).
    """
    r, t = wp.tid()
    base = t * BLOCK
    h_max = bounds[r][1]
    window = reach_inclusive(d + h_max, curvature)
    c = first + base
    blocks = (2 * window + BLOCK) // BLOCK
    if window >= 0 and base + BLOCK <= steps and c - window >= 0 and c + blocked_last_read(-window, blocks) < n:
        # every spring the 8 steps read lies on the line: no checks in the inner loops
        acc = blocked_spring_sum(h[r], c, -window, blocks, lifts, lift_origin, d, curvature, block_values())
        for j in range(BLOCK):
            force[r, base + j] = k_spring * acc[j] - offset
    else:
        for j in range(BLOCK):
            s = base + j
            if s < steps:
                force[r, s] = k_spring * force_direct(h, r, n, first + s, d, h_max, curvature, 0, 1) - offset


@wp.func
def direct_lane_force(lines: DirectLines, r: int, c: int, d: wp.float64, contact: Contact, lane: int, lanes: int):
    """This lane's part (N) of F (eq 11-12) with the wheel at spring c of row r, indentation d (m),
    and the row r (:func:`~mdroll.kernels.dynamics.row_index`)."""
    return contact.k_spring * force_direct(lines.h, r, lines.n, c, d, lines.bounds[r][1], contact.curvature, lane,
                                           lanes), r


#: Eq 13 with the direct sum (:func:`mdroll.kernels.dynamics.coupled_dynamics`).
coupled_direct = coupled_dynamics(DirectLines, direct_lane_force)
