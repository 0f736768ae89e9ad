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
from .dynamics import PREPARED_STEPS, PreparedSlot, PreparedSlots, PreparedSums, coupled_dynamics, warp_sums
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
    springs ahead of spring c, at springs 0 and 1 of every 16 (a cache line of each; a build of
    two steps, c of one parity, meets one of them); nothing on the CPU."""
    if lane == 0 and (c & 14) == 0:
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
def extrapolated(d: wp.float64, rise: wp.float64, bend: wp.float64, ahead: int, spread: wp.float64) -> wp.vec2d:
    """The window ``(lo, hi)`` (m) of the indentation ``ahead`` steps after d: d with its last change
    ``rise`` and that change's change ``bend`` carried on, twice as wide a side as they move it,
    and ``spread`` wider."""
    steps = wp.float64(ahead)
    curve = steps * (steps + wp.float64(1.0)) * wp.float64(0.5)
    centre = d + steps * rise + curve * bend
    half = wp.float64(2.0) * (steps * wp.abs(rise) + curve * wp.abs(bend)) + spread
    return wp.vec2d(centre - half, centre + half)


@wp.struct
class BuildScan:
    """The springs that a build of :data:`~mdroll.kernels.dynamics.PREPARED_STEPS` steps, the wheel
    at c, c + 1, ... (:func:`prepared_sum`), classifies, from the reaches ``core`` and ``outer`` of
    its window: every spring at an offset ``core < |l - c - j| <= outer`` from one of the steps'
    wheel positions c + j, scanned as springs ``left <= l < left_end`` (offsets ``-outer`` up to
    those of the last step's core) and ``right <= l < right_end`` (from past the first step's
    core and the left scan to ``outer`` past the last step's wheel), on the row."""

    c: int
    core: int
    outer: int
    right: int
    right_end: int
    left: int
    left_end: int


@wp.func
def build_scan(row: BandRow, c: int, core: int, outer: int) -> BuildScan:
    """The scans of a build with the wheel at c first (:class:`BuildScan`)."""
    inner = wp.max(core, 0)
    last = PREPARED_STEPS - 1
    scan = BuildScan()
    scan.c = c
    scan.core = core
    scan.outer = outer
    scan.left = wp.max(c - outer, 0)
    scan.left_end = wp.min(c + last - inner, row.n)
    scan.right = wp.max(c + wp.max(inner + 1, last - inner), 0)
    scan.right_end = wp.min(c + outer + last + 1, row.n)
    return scan


@wp.func
def tallied(row: BandRow, scan: BuildScan, i: int, end: int, offset: wp.float64, lo: wp.float64, hi: wp.float64,
            curvature: wp.float64, counts: int, totals: PreparedSums, opened: bool):
    """The lane's tallies with spring i (``i < end``: on the scan) at the float64 ``offset = i -
    c``, classified for each step j of the build by its threshold ``curvature (i - c - j)^2 -
    h_i`` (m), the indentation above which it touches: where the spring is in step j's band, in
    contact over the whole window [lo, hi] (threshold below it: counted in byte j of ``counts``,
    summed in ``totals[j]``) or open (threshold in it: ``opened``)."""
    height = load_line(row.h, wp.min(i, row.n - 1))
    inside = i < end
    root = offset  # i - c - j, float64
    shift = i - scan.c  # the same, int
    for j in range(PREPARED_STEPS):
        t = curvature * root * root - height
        away = wp.abs(shift)
        member = inside and away > scan.core and away <= scan.outer
        sure = member and t < lo
        counts += wp.where(sure, int(1) << (8 * j), int(0))
        totals[j] = totals[j] + wp.where(sure, t, wp.float64(0.0))
        opened = opened or (member and lo <= t and t < hi)
        root -= wp.float64(1.0)
        shift -= 1
    return counts, totals, opened


@wp.func
def open_thresholds(row: BandRow, scan: BuildScan, j: int, slots: int, lo: wp.float64, hi: wp.float64,
                    curvature: wp.float64, lane: int, lanes: int) -> wp.vec3d:
    """How many springs of step j's band have their threshold (m) in the window ``[lo, hi)``, and
    the thresholds of the first two (infinite where fewer): each lane's springs scanned again,
    its first two kept, then those of the lowest lanes with any (a reduction, a ballot and
    shuffles; every lane of the warp must call)."""
    count = int(0)
    first = wp.float64(wp.inf)
    second = wp.float64(wp.inf)
    for k in range(2 * slots):
        i = wp.where(k % 2 == 0, scan.right, scan.left) + lane + (k // 2) * lanes
        end = wp.where(k % 2 == 0, scan.right_end, scan.left_end)
        away = wp.abs(i - scan.c - j)
        root = exact_double(away)
        t = curvature * root * root - load_line(row.h, wp.min(i, row.n - 1))
        open_here = i < end and away > scan.core and away <= scan.outer and lo <= t and t < hi
        second = wp.where(open_here and count == 1, t, second)
        first = wp.where(open_here and count == 0, t, first)
        count += wp.where(open_here, 1, 0)
    lanes_open = ballot(count > 0)
    first_lane = lowest_lane(lanes_open)
    u1 = broadcast_float(first, first_lane)
    u2 = wp.where(broadcast_int(count, first_lane) >= 2, broadcast_float(second, first_lane),
                  broadcast_float(first, lowest_lane(lanes_open & (lanes_open - 1))))
    return wp.vec3d(wp.float64(warp_sum_int(count)), u1, u2)


@wp.func
def core_thresholds(row: BandRow, c: int, core: int, curvature: wp.float64) -> wp.vec2d:
    """The count and the sum of thresholds (m) of the springs ``|l - c| <= core`` of the row, in
    closed form from the prefix sums (eq 18-20)."""
    i = wp.min(wp.max(c - core, 0), row.n)
    j = wp.max(wp.min(c + core + 1, row.n), i)
    squares = curvature * sum_of_squares(i - c, j - 1 - c)
    total = wp.where(j > i, squares - (load_line(row.prefix, j) - load_line(row.prefix, i)), wp.float64(0.0))
    return wp.vec2d(wp.float64(j - i), total)


@wp.func
def prepared_sum(lines: SweepLines, band: BandRow, c: int, ahead: int, d: wp.float64, d1: wp.float64,
                 d2: wp.float64, contact: Contact, lane: int, lanes: int) -> PreparedSlots:
    """The forces of the :data:`~mdroll.kernels.dynamics.PREPARED_STEPS` steps with the wheel at
    springs c, c + 1, ..., prepared ``ahead``, ``ahead + 1``, ... steps before them from the
    indentations d, d1, d2 (m) of the step ``ahead`` before c and the two before it, in one build
    from the same loads: a slot ``(lo, hi, ready, N, T, u1, u2, 0)`` each (lane 0's are whole).
    The window [lo, hi] of indentations covers all the steps' (:func:`extrapolated`, at least
    1e-12 of the row's roughness a side). Over it the core ``|l - c - j| <= reach(lo + min h)``
    of step j is in contact (count and sum of thresholds in closed form from the prefix sums),
    and of the bands out to ``reach(hi + max h)`` each lane classifies its springs for every step
    (:class:`BuildScan`, :func:`tallied`), adjacent lanes on adjacent springs: in contact over
    the whole window (threshold below it), open (in it), or out. The warp adds up the counts
    (one integer reduction for all steps) and the sums of thresholds (:func:`~mdroll.kernels.dynamics.warp_sums`) into
    each step's count N and sum T (m) of the thresholds of the springs in contact; only where a
    spring is open (one ballot) do further reductions find how many and the first two's
    thresholds u1, u2 (:func:`open_thresholds`; infinite where none). ``ready`` (1 or 0): the
    bands fit the lanes and at most two springs are open; then, for any d in the window, F = k
    (N d - T + max(d - u1, 0) + max(d - u2, 0))."""
    curvature = contact.curvature
    inverse = wp.float32(1.0) / wp.float32(curvature)
    prefetch_ahead(band, c, lane)
    rise = d - d1
    bend = rise - (d1 - d2)
    spread = wp.float64(1e-12) * (band.high - band.low)
    near = extrapolated(d, rise, bend, ahead, spread)
    far = extrapolated(d, rise, bend, ahead + PREPARED_STEPS - 1, spread)
    lo = wp.where(near[0] < far[0], near[0], far[0])
    hi = wp.where(near[1] > far[1], near[1], far[1])
    core = window_reach(lo + band.low, curvature, inverse)
    scan = build_scan(band, c, core, window_reach(hi + band.high, curvature, inverse))
    widest = wp.max(scan.right_end - scan.right, scan.left_end - scan.left)
    slots = lane_slots((widest + lanes - 1) // lanes)
    counts = int(0)  # byte j: step j's springs in contact over the window
    totals = PreparedSums()
    opened = bool(False)
    right_offset = wp.float64(scan.right + lane - c)  # grows by `lanes` a slot
    left_offset = wp.float64(scan.left + lane - c)
    stride = wp.float64(lanes)
    for k in range(slots):
        step = lane + k * lanes
        counts, totals, opened = tallied(band, scan, scan.right + step, scan.right_end, right_offset, lo, hi,
                                         curvature, counts, totals, opened)
        counts, totals, opened = tallied(band, scan, scan.left + step, scan.left_end, left_offset, lo, hi,
                                         curvature, counts, totals, opened)
        right_offset += stride
        left_offset += stride
    counts = warp_sum_int(counts)
    totals = warp_sums(totals)
    any_open = ballot(opened) != 0
    zero = wp.float64(0.0)
    infinite = wp.float64(wp.inf)
    built = PreparedSlots()
    for j in range(PREPARED_STEPS):
        found = wp.vec3d(zero, infinite, infinite)
        if any_open:
            found = open_thresholds(band, scan, j, slots, lo, hi, curvature, lane, lanes)
        whole = core_thresholds(band, c + j, core, curvature)
        ready = wp.where(widest <= slots * lanes and found[0] <= wp.float64(2.0), wp.float64(1.0), zero)
        built[j] = PreparedSlot(lo, hi, ready, whole[0] + wp.float64((counts >> (8 * j)) & 255), whole[1] + totals[j],
                                found[1], wp.where(found[0] >= wp.float64(2.0), found[2], infinite), zero)
    return built


@wp.func
def prepared_force(lines: SweepLines, row: BandRow, prepared: PreparedSlot, c: int, d: wp.float64,
                   contact: Contact, lane: int, lanes: int):
    """F (N, eq 11-12) with the wheel at spring c of the row, indentation d (m), in every lane,
    from the step's prepared sum (:func:`prepared_sum`), and the row for the next step: with d
    in the window, F = k (N d - T) plus the open springs' ``max(d - u, 0)``, a few operations
    with no load and no reduction; else (or not ready) the band summed directly
    (:func:`lane_band_force`, its reaches carried in the row) and the lanes added up."""
    zero = wp.float64(0.0)
    if prepared[2] > zero and prepared[0] <= d and d <= prepared[1]:
        first = wp.where(d > prepared[5], d - prepared[5], zero)
        second = wp.where(d > prepared[6], d - prepared[6], zero)
        return contact.k_spring * (prepared[3] * d - prepared[4] + first + second), row
    part, moved = lane_band_force(row, c, d, contact, lane, lanes)
    return warp_sum_float(part), moved


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
