"""The sweep's coupled step (eq 13; physics.md sections 4-5): the force at an indentation that
changes every step, so that no running totals carry over from step to step (the decoupled
forms: :mod:`mdroll.kernels.sweep_sequential`, :mod:`mdroll.kernels.sweep_stream`).

What a step needs of its row is read once, before the steps (:func:`band_row`): the addresses
of the row's heights and prefix sums and its bounds, in registers. The two reaches move by a
spring now and then while the wheel rolls on, so each step first tests, exactly, whether last
step's still holds (:func:`settled_reaches`; two comparisons on the step's chain instead of a
square root). The wheel moves one spring a step, so the springs and prefix sums a step will read
are known long before: each step asks the L1 cache for those :data:`PREFETCH_AHEAD` springs
ahead of the wheel, and the step's own loads, which wait on d, find them there.

Known long before too is all of a step's force but its comparison with d: over a window of
indentations, the springs below it touch and those above do not, so F = k (N d - T) plus the
few springs whose threshold lies in the window. :func:`prepared_sum` builds that a few steps
ahead (in helper warps, :func:`mdroll.kernels.dynamics.with_helpers`), and the step itself
(:func:`prepared_force`) is a few operations, summing its band directly only where d left the
window.
"""

import warp as wp

from .common import Contact, exact_double, reach_strict, settle_reach, sum_of_squares
from .dynamics import PreparedSlot, coupled_dynamics
from .intrinsics import (ballot, broadcast_float, broadcast_int, load_line, lowest_lane, prefetch_float_near,
                         rough_sqrt, row_address, warp_sum_float, warp_sum_int)

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


@wp.struct
class BandRow:
    """One row as a coupled step reads it (:func:`band_row`), in registers over the steps: its
    index ``r``, the addresses of its heights ``h`` and prefix sums ``prefix`` (rows contiguous),
    its ``n`` springs and bounds ``low = min h``, ``high = max h`` (m); and the last step's
    reaches, each with the levels ``(from, to]`` (m) over which it holds
    (:func:`settled_reaches`): ``core`` of ``d + low``, ``outer`` of ``d + high``, and the
    core's ``2 core + 1`` springs and ``curvature sum_{|m| <= core} m^2`` (m)."""

    r: int
    h: wp.uint64
    prefix: wp.uint64
    n: int
    low: wp.float64
    high: wp.float64
    core: int
    core_from: wp.float64
    core_to: wp.float64
    core_width: wp.float64
    core_squares: wp.float64
    outer: int
    outer_from: wp.float64
    outer_to: wp.float64


@wp.func
def band_row(h: wp.array2d(dtype=wp.float64), prefix: wp.array2d(dtype=wp.float64), r: int, n: int,
             bounds: wp.vec2d) -> BandRow:
    """Row r of a batch with the bounds ``(min h, max h)`` (m) of the band sums, before the
    first step: no reach holds yet (an empty range of levels)."""
    row = BandRow()
    row.r = r
    row.h = row_address(h, r)
    row.prefix = row_address(prefix, r)
    row.n = n
    row.low = bounds[0]
    row.high = bounds[1]
    row.core = -1
    row.core_from = wp.float64(0.0)
    row.core_to = wp.float64(-1.0)
    row.core_width = wp.float64(0.0)
    row.core_squares = wp.float64(0.0)
    row.outer = -1
    row.outer_from = wp.float64(0.0)
    row.outer_to = wp.float64(-1.0)
    return row


@wp.func
def reach_levels(m: int, curvature: wp.float64) -> wp.vec2d:
    """The levels ``(from, to]`` (m) over which :func:`~mdroll.kernels.common.reach_strict` is m
    (>= -1): ``(fl(fl(curvature m) m), fl(fl(curvature (m+1)) (m+1))]`` by the same float64
    tests, which grow with m; from -infinity for m = -1 (its levels are those <= 0)."""
    low = wp.float64(-wp.inf)
    if m >= 0:
        root = wp.float64(m)
        low = curvature * root * root
    root = wp.float64(m + 1)
    return wp.vec2d(low, curvature * root * root)


@wp.func
def settled_reaches(row: BandRow, d: wp.float64, curvature: wp.float64) -> BandRow:
    """The row with the reaches at indentation d (m): ``core = reach_strict(d + min h)`` and
    ``outer = reach_strict(d + max h)`` (:func:`~mdroll.kernels.common.reach_strict`). Each
    keeps last step's where its level still lies in that reach's range, an exact test; else
    it is found anew with its range (and the core's width and sum of squares)."""
    moved = row
    level = d + row.low
    if not (row.core_from < level and level <= row.core_to):
        core = reach_strict(level, curvature)
        levels = reach_levels(core, curvature)
        moved.core = core
        moved.core_from = levels[0]
        moved.core_to = levels[1]
        moved.core_width = wp.float64(2 * core + 1)
        moved.core_squares = wp.float64(0.0)
        if core >= 0:
            moved.core_squares = curvature * sum_of_squares(-core, core)
    level = d + row.high
    if not (row.outer_from < level and level <= row.outer_to):
        outer = reach_strict(level, curvature)
        levels = reach_levels(outer, curvature)
        moved.outer = outer
        moved.outer_from = levels[0]
        moved.outer_to = levels[1]
    return moved


@wp.func
def prefetch_ahead(row: BandRow, c: int, lane: int):
    """Lane 0 asks the L1 cache for the height and the prefix sum :data:`PREFETCH_AHEAD`
    springs ahead of spring c, every 16th spring (a cache line of each); nothing on the CPU."""
    if lane == 0 and (c & 15) == 0:
        i = wp.min(c + PREFETCH_AHEAD, row.n - 1)
        prefetch_float_near(row.h, i)
        prefetch_float_near(row.prefix, i)


@wp.func
def core_sum(row: BandRow, c: int, d: wp.float64, curvature: wp.float64) -> wp.float64:
    """Exact ``sum_{|l - c| <= core} (h_l + d - curvature (l - c)^2)`` (m) over the row's springs
    (eq 18-20, as :func:`~mdroll.kernels.common.full_contact_sum`): away from the row's ends
    with the core's width and sum of squares of :func:`settled_reaches`."""
    i = c - row.core
    j = c + row.core + 1
    if row.core < 0:
        return wp.float64(0.0)
    if i >= 0 and j <= row.n:
        return (load_line(row.prefix, j) - load_line(row.prefix, i)) + row.core_width * d - row.core_squares
    i = wp.max(i, 0)
    j = wp.min(j, row.n)
    if j <= i:
        return wp.float64(0.0)
    return (load_line(row.prefix, j) - load_line(row.prefix, i)) + wp.float64(j - i) * d - curvature * sum_of_squares(
        i - c, j - 1 - c)


@wp.func
def band_heights(row: BandRow, right: int, left: int, lanes: int) -> wp.vec4d:
    """The heights of springs ``right, right + lanes, left, left + lanes`` (>= 0) of the row,
    each index clamped to its last spring: loaded unconditionally, so that the four loads are
    in flight together (:func:`band_term` drops those past a band's end)."""
    last = row.n - 1
    return wp.vec4d(load_line(row.h, wp.min(right, last)), load_line(row.h, wp.min(right + lanes, last)),
                    load_line(row.h, wp.min(left, last)), load_line(row.h, wp.min(left + lanes, last)))


@wp.func
def band_term(height: wp.float64, l: int, end: int, m: wp.float64, d: wp.float64,
              curvature: wp.float64) -> wp.float64:
    """``max(h_l + d - curvature m^2, 0)`` (m; eq 10) for spring l at offset ``|m|`` (a float64
    integer) from the wheel, of height ``height``, if ``l < end``, else 0: adding it leaves a
    sum of such terms unchanged to the bit."""
    return wp.where(l < end, wp.max(height + d - curvature * m * m, wp.float64(0.0)), wp.float64(0.0))


@wp.func
def banded_force(row: BandRow, c: int, d: wp.float64, contact: Contact, lane: int, lanes: int) -> wp.float64:
    """This lane's part (N) of F (eq 11-12) with the wheel at spring c of the row, indentation d
    (m), from the row's reaches (:func:`settled_reaches`, ``outer >= 0``): lane 0 adds the
    certain core ``|m| <= core`` in closed form (:func:`core_sum`), and the lanes share the two
    bands out to ``outer``, adjacent lanes on adjacent springs, summed spring by spring (eq 10),
    each band in its own sum in the order of :func:`~mdroll.kernels.common.spring_sum`.

    A step's loads all wait on d, so they go out together: the first round's four heights
    (two springs of each band, :func:`band_heights`), then the core's two prefix sums (every
    lane computes the closed form; lane 0 keeps it), and each round's heights load before the
    previous round's terms are added. The offsets are float64 integers, stepped by exact adds."""
    curvature = contact.curvature
    core = row.core
    outer = row.outer
    # right band c+core+1 .. c+outer, left band c-outer .. c-max(core, 0)-1 (core -1: the right one holds c)
    right = wp.max(c + core + 1, 0) + lane
    right_end = wp.min(c + outer + 1, row.n)
    left = wp.max(c - outer, 0) + lane
    left_end = wp.min(c - wp.max(core, 0), row.n)
    heights = band_heights(row, right, left, lanes)
    core_part = core_sum(row, c, d, curvature)
    offset_right = wp.float64(right - c)  # grows by `lanes` a spring
    offset_left = wp.float64(c - left)  # shrinks by `lanes` a spring
    stride = wp.float64(lanes)
    right_sum = wp.float64(0.0)
    left_sum = wp.float64(0.0)
    while right < right_end or left < left_end:
        now = heights
        heights = band_heights(row, right + 2 * lanes, left + 2 * lanes, lanes)
        right_sum += band_term(now[0], right, right_end, offset_right, d, curvature)
        right_sum += band_term(now[1], right + lanes, right_end, offset_right + stride, d, curvature)
        left_sum += band_term(now[2], left, left_end, offset_left, d, curvature)
        left_sum += band_term(now[3], left + lanes, left_end, offset_left - stride, d, curvature)
        right += 2 * lanes
        left += 2 * lanes
        offset_right += stride + stride
        offset_left -= stride + stride
    total = wp.float64(0.0)
    if lane == 0:
        total = core_part
    total += right_sum
    total += left_sum
    return contact.k_spring * total


@wp.func
def lane_band_force(row: BandRow, c: int, d: wp.float64, contact: Contact, lane: int, lanes: int):
    """This lane's part (N) of F (:func:`banded_force`) at this step's reaches, and the row with
    them (:func:`settled_reaches`)."""
    settled = settled_reaches(row, d, contact.curvature)
    if settled.outer < 0:
        return wp.float64(0.0), settled
    return banded_force(settled, c, d, contact, lane, lanes), settled


@wp.func_native("""
#if defined(__CUDA_ARCH__)
return 2;
#else
return springs <= 64 ? springs : 0;
#endif
""")
def lane_slots(springs: int) -> int:
    """Springs of each band side one lane classifies a step (:func:`classified_band`): on CUDA
    2, a warp's 32 lanes 64 a side, a constant so that the classification is straight-line
    code; on the CPU, one lane, the band's ``springs`` a side up to the same 64, none beyond
    (the step is then summed directly)."""
    ...


@wp.func
def sweep_row(lines: SweepLines, r: int, contact: Contact) -> BandRow:
    """The sweep's row set-up for the coupled dynamics (:func:`band_row`)."""
    return band_row(lines.h, lines.prefix, r, lines.n, lines.bounds[r])


@wp.func
def window_reach(level: wp.float64, curvature: wp.float64, inverse: wp.float32) -> int:
    """:func:`~mdroll.kernels.common.reach_strict` of ``level`` (m) without a branch: the guess
    from an approximate float32 square root (within one of the reach), settled by the float64
    tests (-1 for ``level <= 0``)."""
    guess = int(rough_sqrt(wp.float32(wp.max(level, wp.float64(0.0))) * inverse))
    return settle_reach(guess, level, curvature)


@wp.func
def threshold(row: BandRow, i: int, end: int, c: int, curvature: wp.float64) -> wp.float64:
    """Spring i's threshold ``curvature (i - c)^2 - h_i`` (m), the indentation above which it
    touches with the wheel at spring c; infinite for ``i >= end`` (past its band)."""
    m = exact_double(wp.abs(i - c))
    height = load_line(row.h, wp.min(i, row.n - 1))
    return wp.where(i < end, curvature * m * m - height, wp.float64(wp.inf))


@wp.struct
class LaneSum:
    """One lane's part of a window's classification (:func:`classified`): the count and sum of
    thresholds (m) of its springs in contact over the whole window (threshold below it), and
    of those whose threshold lies in it (``open``) the first two."""

    count: int
    total: wp.float64
    open: int
    first: wp.float64
    second: wp.float64


@wp.func
def classified(part: LaneSum, t: wp.float64, lo: wp.float64, hi: wp.float64) -> LaneSum:
    """The lane's part with one more spring of threshold t (m), against the window [lo, hi]."""
    sure = t < lo
    open_here = (not sure) and t < hi
    part.count += wp.where(sure, 1, 0)
    part.total += wp.where(sure, t, wp.float64(0.0))
    part.second = wp.where(open_here and part.open == 1, t, part.second)
    part.first = wp.where(open_here and part.open == 0, t, part.first)
    part.open += wp.where(open_here, 1, 0)
    return part


@wp.func
def prepared_sum(lines: SweepLines, band: BandRow, c: int, ahead: int, d: wp.float64, d1: wp.float64,
                 d2: wp.float64, contact: Contact, lane: int, lanes: int) -> PreparedSlot:
    """The force of the step with the wheel at spring c, prepared ``ahead`` steps before it from
    the indentations d, d1, d2 (m) of that step and the two before: ``(lo, hi, ready, N, T, u1,
    u2, 0)``. The window [lo, hi] of indentations: d and its last two changes extrapolated,
    twice as wide as the extrapolation moves d (at least 1e-12 of the row's roughness). Over
    it the core ``|l - c| <= reach(lo + min h)`` is in contact (count and sum of thresholds in
    closed form from the prefix sums), and of the bands out to ``reach(hi + max h)`` each lane
    classifies its springs, adjacent lanes on adjacent springs (:func:`classified`): in contact
    over the whole window, open, or out. The warp adds the counts and sums up (one integer
    reduction, one float64 butterfly) into the count N and the sum T (m) of the thresholds of
    the springs in contact, and a ballot finds the open ones' thresholds u1, u2 (infinite if
    none). ``ready`` (1 or 0): the bands fit the lanes and at most two springs are open; then,
    for any d in the window, F = k (N d - T + max(d - u1, 0) + max(d - u2, 0))."""
    curvature = contact.curvature
    inverse = wp.float32(1.0) / wp.float32(curvature)
    prefetch_ahead(band, c, lane)
    rise = d - d1
    bend = rise - (d1 - d2)
    steps = wp.float64(ahead)
    curve = steps * (steps + wp.float64(1.0)) * wp.float64(0.5)
    centre = d + steps * rise + curve * bend
    half = wp.float64(2.0) * (steps * wp.abs(rise) + curve * wp.abs(bend)) + wp.float64(1e-12) * (
        band.high - band.low)
    lo = centre - half
    hi = centre + half
    core = window_reach(lo + band.low, curvature, inverse)
    outer = window_reach(hi + band.high, curvature, inverse)
    right = wp.max(c + core + 1, 0)
    right_end = wp.min(c + outer + 1, band.n)
    left = wp.max(c - outer, 0)
    left_end = wp.min(c - wp.max(core, 0), band.n)
    widest = wp.max(right_end - right, left_end - left)
    slots = lane_slots((widest + lanes - 1) // lanes)
    i = wp.min(wp.max(c - core, 0), band.n)
    j = wp.max(wp.min(c + core + 1, band.n), i)
    squares = curvature * sum_of_squares(i - c, j - 1 - c)
    core_sum = wp.where(j > i, squares - (load_line(band.prefix, j) - load_line(band.prefix, i)), wp.float64(0.0))
    part = LaneSum()
    part.count = 0
    part.total = wp.float64(0.0)
    part.open = 0
    part.first = wp.float64(wp.inf)
    part.second = wp.float64(wp.inf)
    for k in range(slots):
        step = lane + k * lanes
        part = classified(part, threshold(band, right + step, right_end, c, curvature), lo, hi)
        part = classified(part, threshold(band, left + step, left_end, c, curvature), lo, hi)
    counts = warp_sum_int(part.count + part.open * 65536)
    opened = counts >> 16
    lanes_open = ballot(part.open > 0)
    first_lane = lowest_lane(lanes_open)
    u1 = broadcast_float(part.first, first_lane)
    u2 = wp.where(broadcast_int(part.open, first_lane) >= 2, broadcast_float(part.second, first_lane),
                  broadcast_float(part.first, lowest_lane(lanes_open & (lanes_open - 1))))
    ready = wp.where(widest <= slots * lanes and opened <= 2, wp.float64(1.0), wp.float64(0.0))
    infinite = wp.float64(wp.inf)
    return PreparedSlot(lo, hi, ready, wp.float64(j - i + (counts & 65535)), core_sum + warp_sum_float(part.total),
                        wp.where(opened >= 1, u1, infinite), wp.where(opened >= 2, u2, infinite), wp.float64(0.0))


@wp.func
def prepared_force(lines: SweepLines, row: BandRow, prepared: PreparedSlot, c: int, d: wp.float64,
                   contact: Contact, lane: int, lanes: int):
    """F (N, eq 11-12) with the wheel at spring c of the row, indentation d (m), in every lane,
    from the step's prepared sum (:func:`prepared_sum`), and the row for the next step: with d
    in the window, F = k (N d - T) plus the open springs' ``max(d - u, 0)``, a few operations
    with no load and no reduction; else (or not ready) the band summed directly
    (:func:`lane_band_force`, its reaches carried in the row) and the lanes added up."""
    zero = wp.float64(0.0)
    F = contact.k_spring * (prepared[3] * d - prepared[4] + wp.max(d - prepared[5], zero) + wp.max(d - prepared[6],
                                                                                                    zero))
    moved = row
    if not (prepared[2] > zero and prepared[0] <= d and d <= prepared[1]):
        part, moved = lane_band_force(row, c, d, contact, lane, lanes)
        F = warp_sum_float(part)
    return F, moved


@wp.func
def sweep_lane_force(lines: SweepLines, row: BandRow, c: int, d: wp.float64, contact: Contact, lane: int,
                     lanes: int):
    """This lane's part (N) of F (eq 11-12) with the wheel at spring c of the row, indentation d
    (m), for the coupled dynamics, where d changes every step and no totals carry over: the
    core in closed form and the bands spring by spring (:func:`lane_band_force`), the springs
    prefetched. O(band) a step: ~44 springs a side at the thesis's defaults, growing as 1 / dx
    under refinement. Returns the part and the row with this step's reaches."""
    prefetch_ahead(row, c, lane)
    return lane_band_force(row, c, d, contact, lane, lanes)


#: Eq 13 with the sweep's coupled step (:func:`mdroll.kernels.dynamics.coupled_dynamics`), and
#: its steps prepared ahead by helper warps (:func:`prepared_sum`, :func:`prepared_force`).
coupled_sweep = coupled_dynamics(SweepLines, sweep_lane_force, sweep_row, prepared=(prepared_sum, prepared_force))
