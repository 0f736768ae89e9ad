"""The sweep's sequential form, exact in O(n) at fixed indentation (physics.md section 4; not in
the thesis): the CPU's, where Warp runs one lane a thread.

The sweep. With ``curvature = dx^2 / R`` spring i touches the wheel centred on spring c iff
``|i - c| <= M_i``, M_i the largest integer m >= 0 with ``h_i + d - curvature m^2 > 0``
(none if ``h_i + d <= 0``): M_i is :func:`~mdroll.kernels.common.reach_strict` of the level
``h_i + d``, the same floating-point test ``fl(h_i + d) > fl(fl(curvature m) m)`` that decides
``max(u, 0) > 0`` in the direct sum's ``spring_sum`` (a fused multiply-add there can move the
decision only for ``|u|`` within an ulp of the level, where the spring adds nothing
measurable). So spring i is in contact for the wheel positions ``c in [i - M_i, i + M_i]``: it
enters at ``c = i - M_i`` and leaves after ``c = i + M_i``, and the force (eq 10-12)

    F(c) = k ( sum_{C(c)} h_i + N(c) d - curvature sum_{C(c)} (i - c)^2 ),   C(c) = {i : |i - c| <= M_i}

follows from running totals over the contact set C(c), changed only by these events. Two forms
run it: the stream (:mod:`mdroll.kernels.sweep_stream`, CUDA's), in which a block sweeps a long
segment chunk by chunk, and the sequential form here. Both equal the direct sum to rounding.

An anchor at step c: with ``core`` the reach of ``d + min h`` of the row (every spring reaches
that far) and ``outer`` the reach of ``d + max h`` (no spring reaches farther), the springs
``|m| <= core`` touch whatever h is: a closed form (count, prefix sums S_j of eq 18, ``sum
m^2``), as in the tree's kernel; each of the band springs ``core < |m| <= outer`` is tested
one by one.

Sequential (one thread: one row and a chunk of consecutive steps): with ``V = sum (h_i -
curvature m^2)`` and ``P = sum m`` over the contact set, m the offsets from the wheel, the force
is ``F = k (V + N d)`` and one step moves every offset by -1:
``V(c + 1) = V(c) + curvature (2 P - N)``, ``P(c + 1) = P - N``, before the springs that enter
or leave at c + 1 change the totals. At step c the thread reads spring ``c + outer`` (the last
that can enter at c; it enters within ``band = outer - max(core, 0)`` steps) and spring
``c - max(core, 0) - 1`` (the first whose exit can fall at c; it leaves within ``band`` steps),
records each event in the ring slot of the step it happens at, then applies and clears the slot
of step c. The chunk starts from the anchor at its first step. N and P are exact integers; V
carries one rounding a step (~1e-17 m at the defaults) and restarts from the anchor every
chunk, so the work is O(1) a step and O(n) a line at any resolution.
"""

import warp as wp

from .common import reach_strict, sum_of_squares


#: An event's count change sits above bit 40 of its packed int64, its offsets' change below: the
#: latter is never negative (an entry adds its reach M >= 0, an exit removes offset -M - 1), and a
#: slot's sum stays below 2^40 for any supported band and reach, so the two never mix.
COUNT_SHIFT = wp.constant(wp.int64(40))
COUNT_UNIT = wp.constant(wp.int64(1 << 40))
OFFSET_MASK = wp.constant(wp.int64((1 << 40) - 1))


@wp.func
def packed_event(count: int, offsets: int) -> wp.int64:
    """An event's count change (+1 enters, -1 leaves) and offsets' change (>= 0), packed in one
    int64: ``count 2^40 + offsets``; a sum of them unpacks as ``(sum >> 40, sum & (2^40 - 1))``."""
    return wp.int64(count) * COUNT_UNIT + wp.int64(offsets)


@wp.func
def record_event(
    ring_packed: wp.array3d(dtype=wp.int64),
    ring_value: wp.array3d(dtype=wp.float64),
    r: int,
    j: int,
    at: int,
    slots: int,
    sign: int,
    m: int,
    h: wp.float64,
    curvature: wp.float64,
):
    """Record in ring slot ``at`` (brought back once past ``slots``) of thread (r, j) a spring of
    height h (m) entering (``sign`` +1) at offset m, or leaving (-1) from offset m: N changes by
    ``sign``, P by ``sign m`` (never negative: an exit's m is ``-reach - 1``), V by
    ``sign (h - curvature m^2)``."""
    slot = at
    if slot >= slots:
        slot -= slots
    ring_packed[r, j, slot] += packed_event(sign, sign * m)
    ring_value[r, j, slot] += wp.float64(sign) * (h - curvature * wp.float64(m) * wp.float64(m))


@wp.kernel(enable_backward=False)
def contact_force_sequential(
    lines: wp.array2d(dtype=wp.float64),
    prefix: wp.array2d(dtype=wp.float64),
    bounds: wp.array(dtype=wp.vec2d),
    n: int,
    first: int,
    steps: int,
    chunk: int,
    d: wp.float64,
    curvature: wp.float64,
    k_spring: wp.float64,
    offset: wp.float64,
    ring_packed: wp.array3d(dtype=wp.int64),
    ring_value: wp.array3d(dtype=wp.float64),
    force: wp.array2d(dtype=wp.float64),
):
    """``force[r, s] = F - offset`` (N): F (eq 10-12) with the wheel at spring ``first + s`` of
    row r, indentation d (m), for the ``chunk`` steps s of thread (r, j), swept in order;
    ``ring_*[r, j]`` (at least ``band + 1`` slots, cleared here) hold its pending events."""
    r, j = wp.tid()
    slots = ring_packed.shape[2]
    for k in range(slots):
        ring_packed[r, j, k] = wp.int64(0)
        ring_value[r, j, k] = wp.float64(0.0)
    s_begin = j * chunk
    s_end = wp.min(s_begin + chunk, steps)
    row = lines[r]
    box = bounds[r]
    core = reach_strict(d + box[0], curvature)  # every spring reaches this far (-1: none surely)
    outer = reach_strict(d + box[1], curvature)  # no spring reaches farther
    near = wp.max(core, 0)

    # the anchor: the contact set at the chunk's first step c, and the events the band springs
    # have pending (slot k: k steps after c)
    c = first + s_begin
    count = wp.int64(0)
    offsets = wp.int64(0)
    level = wp.float64(0.0)
    if core >= 0:
        count = wp.int64(2 * core + 1)
        level = (prefix[r, c + core + 1] - prefix[r, c - core]) - curvature * sum_of_squares(-core, core)
    for m in range(core + 1, outer + 1):  # right band: in contact, or entering at m - reach
        if c + m < n:
            h = row[c + m]
            reach = reach_strict(h + d, curvature)
            if reach >= m:
                count += wp.int64(1)
                offsets += wp.int64(m)
                level += h - curvature * wp.float64(m) * wp.float64(m)
            elif reach >= 0:
                record_event(ring_packed, ring_value, r, j, m - reach, slots, 1, reach, h, curvature)
    for m in range(-outer, -near):  # left band: in contact, and leaving at m + reach + 1
        if c + m >= 0:
            h = row[c + m]
            reach = reach_strict(h + d, curvature)
            if reach >= -m:
                count += wp.int64(1)
                offsets += wp.int64(m)
                level += h - curvature * wp.float64(m) * wp.float64(m)
                record_event(ring_packed, ring_value, r, j, m + reach + 1, slots, -1, -reach - 1, h, curvature)
    force[r, s_begin] = k_spring * (level + wp.float64(count) * d) - offset

    slot = int(0)  # the ring slot of the current step (slot of step t: t mod slots)
    for s in range(s_begin + 1, s_end):
        wheel = first + s
        slot += 1
        if slot == slots:
            slot = 0
        if wheel + outer < n:  # enters outer - reach steps later, at offset reach
            h = row[wheel + outer]
            reach = reach_strict(h + d, curvature)
            if reach >= 0:
                record_event(ring_packed, ring_value, r, j, slot + outer - reach, slots, 1, reach, h, curvature)
        if wheel - near - 1 >= 0:  # leaves reach - near steps later, from offset -reach - 1
            h = row[wheel - near - 1]
            reach = reach_strict(h + d, curvature)
            if reach >= 0:
                record_event(ring_packed, ring_value, r, j, slot + reach - near, slots, -1, -reach - 1, h,
                             curvature)
        # one step: every offset -1, then the step's events
        level += curvature * wp.float64(wp.int64(2) * offsets - count)
        offsets -= count
        packed = ring_packed[r, j, slot]
        count += packed >> COUNT_SHIFT
        offsets += packed & OFFSET_MASK
        level += ring_value[r, j, slot]
        ring_packed[r, j, slot] = wp.int64(0)
        ring_value[r, j, slot] = wp.float64(0.0)
        if count == wp.int64(0):
            level = wp.float64(0.0)  # no contact: exactly no force, and no drift carried on
        force[r, s] = k_spring * (level + wp.float64(count) * d) - offset
