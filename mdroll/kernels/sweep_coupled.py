"""The sweep's coupled step (eq 13; physics.md sections 4-5): the force at an indentation that
changes every step, so that no running totals carry over from step to step (the decoupled
forms: :mod:`mdroll.kernels.sweep_sequential`, :mod:`mdroll.kernels.sweep_stream`).

The wheel moves one spring a step, so the springs and prefix sums a step will read are known
long before: each step asks the L1 cache for those :data:`PREFETCH_AHEAD` springs ahead of the
wheel, and the step's own loads, which wait on d, find them there.
"""

import warp as wp

from .common import Contact, full_contact_sum, reach_strict
from .dynamics import coupled_dynamics
from .intrinsics import prefetch_float_near, row_address

#: Springs ahead of the wheel whose heights and prefix sums a coupled step prefetches: past the
#: band's far edge (reach(d + max h), ~850 springs at the thesis's defaults), so that a line of
#: the cache arrives long before a step reads it.
PREFETCH_AHEAD = 1024


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
def prefetch_ahead(h: wp.array2d(dtype=wp.float64), prefix: wp.array2d(dtype=wp.float64), r: int, c: int, n: int,
                   lane: int):
    """Lane 0 asks the L1 cache for the height and the prefix sum :data:`PREFETCH_AHEAD`
    springs ahead of spring c of row r (rows contiguous); nothing on the CPU."""
    if lane == 0:
        i = wp.min(c + PREFETCH_AHEAD, n - 1)
        prefetch_float_near(row_address(h, r), i)
        prefetch_float_near(row_address(prefix, r), i)


@wp.func
def band_heights(h: wp.array2d(dtype=wp.float64), r: int, right: int, left: int, lanes: int, n: int) -> wp.vec4d:
    """The heights of springs ``right, right + lanes, left, left + lanes`` of row r, each index
    clamped into the row: loaded unconditionally, so that the four loads are in flight together
    (:func:`band_term` drops those past a band's end)."""
    last = n - 1
    return wp.vec4d(h[r, wp.clamp(right, 0, last)], h[r, wp.clamp(right + lanes, 0, last)],
                    h[r, wp.clamp(left, 0, last)], h[r, wp.clamp(left + lanes, 0, last)])


@wp.func
def band_term(height: wp.float64, l: int, end: int, c: int, d: wp.float64, curvature: wp.float64) -> wp.float64:
    """``max(h_l + d - curvature (l - c)^2, 0)`` (m; eq 10) for spring l of height ``height`` if
    ``l < end``, else 0: adding it leaves a sum of such terms unchanged to the bit."""
    m = wp.float64(l - c)
    return wp.where(l < end, wp.max(height + d - curvature * m * m, wp.float64(0.0)), wp.float64(0.0))


@wp.func
def banded_force(h: wp.array2d(dtype=wp.float64), prefix: wp.array2d(dtype=wp.float64), r: int, n: int, c: int,
                 d: wp.float64, core: int, outer: int, contact: Contact, lane: int, lanes: int) -> wp.float64:
    """This lane's part (N) of F (eq 11-12) with the wheel at spring c of row r, indentation d
    (m), from the reaches ``core = reach_strict(d + min h)`` and ``outer = reach_strict(d + max
    h)`` (>= 0) of the row's bounds: lane 0 adds the certain core ``|m| <= core`` in closed form
    (eq 18-20, as the sweep's anchor), and the lanes share the two bands out to ``outer``,
    adjacent lanes on adjacent springs, summed spring by spring (eq 10), each band in its own
    sum in the order of :func:`~mdroll.kernels.common.spring_sum`.

    A step's loads all wait on d, so they go out together: the first round's four heights
    (two springs of each band, :func:`band_heights`), then the core's two prefix sums (every
    lane computes the closed form; lane 0 keeps it), and each round's heights load before the
    previous round's terms are added."""
    curvature = contact.curvature
    # right band c+core+1 .. c+outer, left band c-outer .. c-max(core, 0)-1 (core -1: the right one holds c)
    right = wp.max(c + core + 1, 0) + lane
    right_end = wp.min(c + outer + 1, n)
    left = wp.max(c - outer, 0) + lane
    left_end = wp.min(c - wp.max(core, 0), n)
    heights = band_heights(h, r, right, left, lanes, n)
    core_sum = full_contact_sum(prefix, r, wp.max(c - core, 0), wp.min(c + core + 1, n), c, d, curvature)
    right_sum = wp.float64(0.0)
    left_sum = wp.float64(0.0)
    while right < right_end or left < left_end:
        now = heights
        heights = band_heights(h, r, right + 2 * lanes, left + 2 * lanes, lanes, n)
        right_sum += band_term(now[0], right, right_end, c, d, curvature)
        right_sum += band_term(now[1], right + lanes, right_end, c, d, curvature)
        left_sum += band_term(now[2], left, left_end, c, d, curvature)
        left_sum += band_term(now[3], left + lanes, left_end, c, d, curvature)
        right += 2 * lanes
        left += 2 * lanes
    total = wp.float64(0.0)
    if lane == 0:
        total = core_sum
    total += right_sum
    total += left_sum
    return contact.k_spring * total


@wp.func
def sweep_lane_force(lines: SweepLines, r: int, c: int, d: wp.float64, contact: Contact, lane: int,
                     lanes: int) -> wp.float64:
    """This lane's part (N) of F (eq 11-12) with the wheel at spring c of row r, indentation d (m),
    for the coupled dynamics, where d changes every step and no totals carry over: the core in
    closed form and the bands spring by spring (:func:`banded_force`). O(band) a step: ~44
    springs a side at the thesis's defaults, growing as 1 / dx under refinement. Both reaches
    are computed before either is tested, side by side."""
    prefetch_ahead(lines.h, lines.prefix, r, c, lines.n, lane)
    box = lines.bounds[r]
    outer = reach_strict(d + box[1], contact.curvature)  # no spring reaches farther
    core = reach_strict(d + box[0], contact.curvature)  # every spring reaches this far (-1: none surely)
    if outer < 0:
        return wp.float64(0.0)
    return banded_force(lines.h, lines.prefix, r, lines.n, c, d, core, outer, contact, lane, lanes)


#: Eq 13 with the sweep's coupled step (:func:`mdroll.kernels.dynamics.coupled_dynamics`).
coupled_sweep = coupled_dynamics(SweepLines, sweep_lane_force)
