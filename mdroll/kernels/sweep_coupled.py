"""The sweep's coupled step (eq 13; physics.md sections 4-5): the force at an indentation that
changes every step, so that no running totals carry over from step to step (the decoupled
forms: :mod:`mdroll.kernels.sweep_sequential`, :mod:`mdroll.kernels.sweep_stream`)."""

import warp as wp

from .common import Contact, full_contact_sum, reach_strict, spring_sum
from .dynamics import coupled_dynamics


@wp.struct
class SweepLines:
    """What the sweep's coupled step reads of a batch of lines: heights ``h`` (m, rows of ``n``
    springs), prefix sums ``prefix`` (m; eq 18, (R, n + 1)) and each row's ``bounds = (min h,
    max h)`` (m)."""

    h: wp.array2d(dtype=wp.float64)
    prefix: wp.array2d(dtype=wp.float64)
    bounds: wp.array(dtype=wp.vec2d)
    n: int


@wp.func
def sweep_lane_force(lines: SweepLines, r: int, c: int, d: wp.float64, contact: Contact, lane: int,
                     lanes: int) -> wp.float64:
    """This lane's part (N) of F (eq 11-12) with the wheel at spring c of row r, indentation d (m),
    for the coupled dynamics, where d changes every step and no totals carry over: lane 0 adds
    the certain core ``|m| <= reach(d + min h)`` in closed form (eq 18-20, as the sweep's anchor),
    and the lanes share the two bands out to ``reach(d + max h)``, adjacent lanes on adjacent
    springs, summed spring by spring (eq 10). O(band) a step: ~44 springs a side at the thesis's
    defaults, growing as 1 / dx under refinement."""
    box = lines.bounds[r]
    outer = reach_strict(d + box[1], contact.curvature)  # no spring reaches farther
    if outer < 0:
        return wp.float64(0.0)
    core = reach_strict(d + box[0], contact.curvature)  # every spring reaches this far (-1: none surely)
    total = wp.float64(0.0)
    if lane == 0:
        total = full_contact_sum(lines.prefix, r, wp.max(c - core, 0), wp.min(c + core + 1, lines.n), c, d,
                                 contact.curvature)
    # right band c+core+1 .. c+outer, left band c-outer .. c-max(core, 0)-1 (core -1: the right one holds c)
    total += spring_sum(lines.h, r, wp.max(c + core + 1, 0) + lane, wp.min(c + outer + 1, lines.n), lanes, c, d,
                        contact.curvature)
    total += spring_sum(lines.h, r, wp.max(c - outer, 0) + lane, wp.min(c - wp.max(core, 0), lines.n), lanes, c, d,
                        contact.curvature)
    return contact.k_spring * total


#: Eq 13 with the sweep's coupled step (:func:`mdroll.kernels.dynamics.coupled_dynamics`).
coupled_sweep = coupled_dynamics(SweepLines, sweep_lane_force)
