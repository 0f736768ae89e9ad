"""The sweep's stream form: a block sweeps a long segment of one row in chunks, carrying its totals
and its pending events from chunk to chunk (physics.md section 4; the sweep's exact O(n) force at
fixed indentation, :mod:`mdroll.kernels.sweep_sequential` for the events and the reach M_i).

Per block: row r and the steps of one segment, ``c = first + s`` for s in [s_begin, s_end), in
chunks of ``T = lanes x S`` steps, lane l owning the S consecutive steps ``c0 + l S + q``.

State at step c, over the contact set C(c) (offsets ``m = i - c``): the count N, ``P = sum m``,
and ``U = sum (h_i + d - curvature m^2)`` (m), so that ``F = k U`` (eq 10-12). From step c - 1 to
c every offset drops by one: ``U += curvature (2 P - N)``, ``P -= N`` (exact integers), then the
springs that enter at c (offset +M, value ``u_i = h_i + d - curvature M_i^2 > 0``) join, and those
whose last step was c - 1 (offset -M - 1 after the shift, value ``u_i - curvature (2 M_i + 1)``)
leave. U is kept as ``U_anchor + curvature Z + Y / scale`` with two exact int64 totals: Z sums
the shifts' ``2 P - N``, Y the springs' values in fixed point, ``scale = unit / curvature`` for
an integer unit: a spring enters with ``round(u_i scale)`` and leaves with ``unit (2 M_i + 1) -
round(u_i scale)``, its value then to the very integer, so no rounding accumulates along the
segment (a member's error is at most ``0.5 / scale``, below 1e-13 F_N for any band).

Events: a spring enters at ``i - M_i`` and leaves after ``i + M_i``. With ``near = max(core, 0)``
(the certain core, :func:`~mdroll.kernels.common.reach_strict` of ``d + min h``) and ``outer``
(the reach of ``d + max h``), a chunk starting at c0 reads the entering springs
``c0 + outer + j`` (j < T), whose entries fall at steps in ``[c0 + j, c0 + j + band]``,
``band = outer - near``. With the *delay line* the same read also puts the spring's leaving
event in the ring, ``2 M_i + 1`` steps after its entry (ring ``RING >= T + 2 outer + 1`` bins):
one read, one reach and one fixed-point value a spring. Without it (where that ring would cost
occupancy: long reaches, fine lines) the chunk reads its leaving springs ``c0 - near - 1 + j``
a second time, their events falling in ``[c0 + j, c0 + j + band]`` too (``RING >= T + band``).
A bin holds four int32 sums, each in its own array of the ring: the counts (entries + 2^16
leavers), the lags ``M - near`` of both kinds (a kind's lags are distinct within a bin, so the
sum stays below band (band + 1)), and the values in a 16-bit low limb and a high limb (``unit``
sized from the band so that no limb sum passes 2^31).

Chunk: (1) each lane adds the events of its S entering springs (loaded while the chunk before
ran, so that their latency overlaps a chunk's work) and, without the delay line, of its S
leaving springs to the ring (shared-memory int32 atomics), and starts loading the next chunk's
entering springs; barrier. (2) each lane reads its S
bins and composes their transitions into one affine map of the state (``N -> N + a``,
``P -> P - k N + b``, ``Z -> Z + 2 k P - k^2 N + c``, ``Y -> Y + y`` over k steps): warp
shuffles scan the lanes' maps, the warps' totals go through shared memory (one barrier), and
each lane applies the chunk's incoming state, the warps before it and the lanes before it.
(3) each lane steps through its S bins again, leaving each step's ``F - offset`` in the bin's
first two words; the warp then writes its steps out in order (adjacent lanes, adjacent steps)
and clears the bins; a barrier closes the chunk. The last lane leaves the chunk's outgoing
state for the next chunk.
The segment starts from an anchor at ``a = c0 - 1``, spring by spring (no prefix sums: the CUDA
build is then the row bounds alone): its members' sums, and the events of the springs of the
window that enter (and, with the delay line, leave) later. Its window and first chunk are
prefetched into L2 while the ring is zeroed, and read ANCHOR_LOADS springs a lane at a time.
"""

import functools

import warp as wp

from .common import exact_double, reach_strict, settle_reach
from .intrinsics import (load_float, prefetch_float, row_address, set_shared_float, set_shared_float_words, set_shared_int,
                         set_shared_int64, shared_add, shared_float, shared_float_words, shared_int, shared_int64,
                         shuffle_up, shuffle_xor, shuffle_xor_float, store_float, sync_block, sync_warp)

#: Events a bin can count of each kind: entries add 1 to the bin's count word, leavers 2^16.
COUNT_SHIFT = 16
#: The widest band the ring's int32 sums allow: a bin takes at most band + 1 entries and band + 1
#: leavers (each kind has distinct lags <= band), so each kind's count stays below 2^16, the lag
#: sum below band (band + 1) and the low limbs' sum, 2 (band + 1) (2^16 - 1), below 2^31.
MAX_STREAM_BAND = 16382
#: A chunk's ring needs T + band bins (T + 2 outer + 1 with the delay line); it comes in multiples
#: of RING_UNIT bins, each bin four int32 words, one in each of four arrays (a warp's atomics on
#: consecutive bins then meet 32 banks, not 8 as with a bin's words together), padded one word
#: in 32.
RING_UNIT = 256
BIN_WORDS = 4
BIN_BYTES = BIN_WORDS * 4 * 33 / 32
#: The anchor loads its window's springs this many a lane at once, so that their latencies
#: overlap (four spilled 4 registers at the thesis layout's 128 a lane; two spill none).
ANCHOR_LOADS = 2
#: float64 values an L2 cache line holds: a prefetch asks for one line.
LINE = 16


#: An affine map of the state over k steps (k implicit): (a, b, c, y), see the module docstring.
step_map = wp.types.vector(length=4, dtype=wp.int64)
#: The state: (N, P, Z, Y).
state4 = wp.types.vector(length=4, dtype=wp.int64)


@wp.func
def apply_map(state: state4, f: step_map, k: wp.int64) -> state4:
    """The state after k steps of the map f: ``(N + a, P - k N + b, Z + 2 k P - k^2 N + c, Y + y)``."""
    n = state[0]
    p = state[1]
    return state4(n + f[0], p - k * n + f[1], state[2] + wp.int64(2) * k * p - k * k * n + f[2], state[3] + f[3])


@wp.func
def then_map(first: step_map, second: step_map, k_second: wp.int64) -> step_map:
    """The map of ``first`` followed by ``second`` (``k_second`` steps)."""
    return step_map(apply_map(state4(first[0], first[1], first[2], first[3]), second, k_second))


@wp.func
def step(state: state4, counts: int, lags: int, y: wp.int64, near: int) -> state4:
    """One step: every offset drops by one, then a bin's events: ``counts`` packs the entries and
    2^16 times the leavers, ``lags`` sums their lags ``M - near``, y their fixed-point values.
    An entry adds offset M, a leaver takes offset -(M + 1) away: both add ``near + lag`` to P,
    a leaver 1 more."""
    n = state[0]
    p = state[1]
    entering = counts & 0xFFFF
    leaving = counts >> COUNT_SHIFT
    moved = wp.int64(near) * wp.int64(entering + leaving) + wp.int64(leaving + lags)
    return state4(n + wp.int64(entering - leaving), p - n + moved, state[2] + wp.int64(2) * p - n, state[3] + y)


@wp.func_native("""
double shifted = value * scale + 6755399441055744.0;  // + 1.5 2^52: the integer part lands in the low bits
#if defined(__CUDA_ARCH__)
long long bits = __double_as_longlong(shifted);
#else
long long bits;
memcpy(&bits, &shifted, sizeof(bits));
#endif
return (bits & 0xFFFFFFFFFFFFFLL) - 2251799813685248LL;
""")
def fixed_value(value: wp.float64, scale: wp.float64) -> wp.int64:
    """``value scale`` rounded to the nearest integer (ties to even; ``|value scale| < 2^51``): a
    spring's value in the ring's fixed point, by the float64 addition of 1.5 2^52 that leaves
    the integer in the low mantissa bits (a float64 to int64 conversion takes several times
    longer on a GPU)."""
    ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
float root = level * inverse_curvature;
float reciprocal;
asm("rsqrt.approx.ftz.f32 %0, %1;" : "=f"(reciprocal) : "f"(fmaxf(root, 1.0e-30f)));
return __float_as_int(__fadd_rz(root * reciprocal, 8388608.0f)) - 0x4B000000;
#else
return (int)sqrtf(level * inverse_curvature);
#endif
""")
def guess_reach(level: wp.float32, inverse_curvature: wp.float32) -> int:
    """``floor(sqrt(level inverse_curvature))`` within a few float32 ulps of the root (level >= 0;
    CUDA: the hardware's reciprocal square root and a float add that leaves the integer part in
    the low mantissa bits, no conversion, which a multiprocessor issues at 1/8 of the rate of an
    add)."""
    ...


@wp.func
def reach_guessed(level: wp.float64, curvature: wp.float64, inverse_curvature: wp.float32) -> int:
    """:func:`~mdroll.kernels.common.reach_strict` (the largest m >= 0 with ``curvature m^2 <
    level``, -1 if level <= 0) from a float32 guess with the curvature's reciprocal
    ``inverse_curvature`` (1/m) and a rough square root (relative error ~1e-6, so within 0.1
    of the root for the offsets up to MAX_CLOSED_FORM_OFFSET), settled by the same float64
    tests, which move it by at most one either way: no division and no slow path."""
    if level <= wp.float64(0.0):
        return -1
    return settle_reach(guess_reach(wp.float32(level), inverse_curvature), level, curvature)


@functools.cache
def stream_kernel(block_dim: int, per_lane: int, ring: int, max_registers: int | None = None, delay: bool = False):
    """The stream kernel for blocks of ``block_dim`` lanes (a multiple of 32 on CUDA, 1 on the
    CPU), ``per_lane`` steps a lane a chunk and a ring of ``ring`` bins (a multiple of 32, at
    least ``block_dim per_lane + band + 1``, or ``block_dim per_lane + 2 outer + 1`` with the
    ``delay`` line), compiled for at most ``max_registers`` registers a lane. Launched by
    ``wp.launch_tiled`` over ``(R, segments)``."""
    BD = block_dim
    S = per_lane
    T = BD * S
    RING = ring
    DELAY = delay
    if ring % 32 or ring < T + 1 or not (BD == 1 or BD % 32 == 0):
        raise ValueError(f"ring = {ring} must be a multiple of 32 above block_dim x per_lane = {T}; "
                         f"block_dim = {BD} 1 or a multiple of 32")
    WARP = min(BD, 32)
    WARPS = BD // WARP
    SCAN_ROUNDS = WARP.bit_length() - 1
    PADDED = RING + RING // 32  # one word of padding in 32: lanes reading S-strided bins meet no bank twice
    WORDS = BIN_WORDS * PADDED
    ANCHOR = 4 * WARPS + 8
    SMALL = ANCHOR + 3 * WARPS  # int64 words: the warps' maps, the carried states (two), the anchor's parts
    K_LANE = S
    K_WARP = WARP * S
    heights = wp.types.vector(length=S, dtype=wp.float64)
    window_heights = wp.types.vector(length=ANCHOR_LOADS, dtype=wp.float64)

    @wp.func_native("""return (uint64_t)(&memory.data(0));""")
    def ring_address(memory: wp.tile(dtype=wp.int32, shape=(WORDS,), storage="shared")) -> wp.uint64: ...

    @wp.func_native("""return (uint64_t)(&memory.data(0));""")
    def small_address(memory: wp.tile(dtype=wp.int64, shape=(SMALL,), storage="shared")) -> wp.uint64: ...

    @wp.func
    def slot(head: int, ahead: int) -> int:
        """The padded ring word of the bin ``ahead`` steps past the chunk's first (whose bin is
        ``head``)."""
        position = head + ahead
        if position >= RING:
            position -= RING
        return position + (position >> 5)

    @wp.func
    def window_offset(j: int, core: int, outer: int, right: int) -> int:
        """The offset m from the anchor of the window's j-th spring: with the delay line
        -outer .. outer, else the right band core + 1 .. outer, then the left -outer .. -near - 1."""
        if wp.static(DELAY):
            return j - outer
        if j >= right:
            return -outer + j - right
        return core + 1 + j

    @wp.func
    def entering_heights(row: wp.uint64, i0: int, lane: int, n: int) -> heights:
        """The lane's S springs ``i0 + q BD + lane`` (-1e300 outside the row: no reach)."""
        loaded = heights()
        for q in range(S):
            i = i0 + q * BD + lane
            loaded[q] = wp.float64(-1.0e300)
            if i >= 0 and i < n:
                loaded[q] = load_float(row, i)
        return loaded

    @wp.func
    def add_event(base: wp.uint64, at: int, lag: int, value: wp.int64, leaving: int):
        """An event in the bin ``at``: its count, its lag ``M - near`` and its fixed-point value,
        in two limbs (low 16 bits and the rest)."""
        if leaving != 0:
            shared_add(base, at, 1 << COUNT_SHIFT)
        else:
            shared_add(base, at, 1)
        shared_add(base, PADDED + at, lag)
        shared_add(base, 2 * PADDED + at, wp.int32(value & wp.int64(0xFFFF)))
        shared_add(base, 3 * PADDED + at, wp.int32(value >> wp.int64(16)))

    @wp.func
    def spring_value(level: wp.float64, reach: int, curvature: wp.float64, scale: wp.float64) -> wp.int64:
        """A spring's entering value ``round(u scale)``, ``u = level - curvature M^2``."""
        root = exact_double(reach)
        return fixed_value(level - curvature * root * root, scale)

    @wp.func
    def leaving_value(value: wp.int64, reach: int, unit: wp.int64) -> wp.int64:
        """The value a spring that entered with ``value`` leaves with: ``unit (2 M + 1)`` less it
        (its ``- curvature (2 M + 1)`` at the offset ``-(M + 1)``, exact)."""
        return unit * wp.int64(2 * reach + 1) - value

    @wp.func
    def step_bin(state: state4, base: wp.uint64, at: int, near: int) -> state4:
        """:func:`step` with the events of the bin at ``at``, read from shared memory."""
        low = wp.int64(shared_int(base, 2 * PADDED + at))
        values = low + (wp.int64(shared_int(base, 3 * PADDED + at)) << wp.int64(16))
        return step(state, shared_int(base, at), shared_int(base, PADDED + at), values, near)

    @wp.kernel(module="unique", enable_backward=False, cuda_max_registers=max_registers)
    def contact_force_stream(
        lines: wp.array2d(dtype=wp.float64),
        bounds: wp.array(dtype=wp.vec2d),
        n: int,
        first: int,
        steps: int,
        segment: int,
        d: wp.float64,
        curvature: wp.float64,
        k_spring: wp.float64,
        offset: wp.float64,
        force: wp.array2d(dtype=wp.float64),
    ):
        """``force[r, s] = F - offset`` (N): F (eq 10-12) with the wheel at spring ``first + s``
        of row r, indentation d (m), for the steps s of this block's segment."""
        r, g, lane = wp.tid()
        s_begin = g * segment
        s_end = wp.min(s_begin + segment, steps)
        box = bounds[r]
        core = reach_strict(d + box[0], curvature)
        outer = reach_strict(d + box[1], curvature)
        forces = row_address(force, r)
        row = row_address(lines, r)
        if outer < 0:  # no spring of the row ever touches
            for s in range(s_begin + lane, s_end, BD):
                store_float(forces, s, -offset)
            return
        near = wp.max(core, 0)
        band = outer - near
        # fixed point: every value lies in [0, curvature (2 outer + 1)] (to a unit), 2^(bits - 1)
        # at most, and a bin sums up to 2 (band + 1) of them: its high limbs (value >> 16) stay
        # below 2^31
        width = int(1)
        while (1 << width) <= band + 1:
            width += 1
        bits = 47 - width
        # Y counts in units of curvature / unit: a leaver's - curvature (2 M + 1) is the exact
        # integer unit (2 M + 1), so it leaves Y with what its entry added less that integer
        unit = (wp.int64(1) << wp.int64(bits - 1)) / wp.int64(2 * outer + 1)
        scale = wp.float64(unit) / curvature
        inverse_scale = curvature / wp.float64(unit)
        inverse_curvature = wp.float32(wp.float64(1.0) / curvature)
        # the anchor's window and the first chunk's springs on their way to L2 while the ring is zeroed
        for i in range(wp.max(first + s_begin - 1 - outer, 0) + LINE * lane, wp.min(first + s_begin + outer + T, n),
                       LINE * BD):
            prefetch_float(row, i)
        memory = wp.tile_zeros(shape=WORDS, dtype=wp.int32, storage="shared")
        base = ring_address(memory)
        small = wp.tile_zeros(shape=SMALL, dtype=wp.int64, storage="shared")
        shared = small_address(small)
        sync_block()  # the zeroed ring before any lane adds to it
        warp = lane / WARP
        in_warp = lane - warp * WARP

        # anchor at a = c0 - 1, spring by spring (the window is ~2 outer springs, a few % of a
        # segment's reads). Without the delay line: the core |m| <= core (all in contact) and
        # the bands, whose springs that enter (right) or leave (left) later put their events in
        # the ring. With it, every spring of the window: those in contact put their leaving
        # events in the ring, those still to come (right) both
        a = first + s_begin - 1
        count = wp.int64(0)
        offsets = wp.int64(0)
        level = wp.float64(0.0)
        right = outer - core  # m = core + 1 .. outer
        left = outer - near  # m = -outer .. -near - 1
        if wp.static(DELAY):
            right = 2 * outer + 1  # m = -outer .. outer
            left = 0
        elif core >= 0:
            lo = wp.max(a - core, 0)
            for i in range(lo + lane, wp.min(a + core + 1, n), BD):
                m = i - a
                count += wp.int64(1)
                offsets += wp.int64(m)
                level += load_float(row, i) + d - curvature * wp.float64(m) * wp.float64(m)
        window = right + left
        for j0 in range(0, window, wp.static(BD * ANCHOR_LOADS)):
            in_window = window_heights()
            for q in range(ANCHOR_LOADS):
                j = j0 + q * BD + lane
                i = a + window_offset(j, core, outer, right)
                in_window[q] = wp.float64(-1.0e300)
                if j < window and i >= 0 and i < n:
                    in_window[q] = load_float(row, i)
            for q in range(ANCHOR_LOADS):
                m = window_offset(j0 + q * BD + lane, core, outer, right)
                level_i = in_window[q] + d
                reach = reach_guessed(level_i, curvature, inverse_curvature)
                if reach >= 0:
                    value = spring_value(level_i, reach, curvature, scale)
                    leaver = leaving_value(value, reach, unit)
                    if reach >= wp.abs(m):
                        count += wp.int64(1)
                        offsets += wp.int64(m)
                        level += level_i - curvature * wp.float64(m) * wp.float64(m)
                        if wp.static(DELAY) or m < 0:
                            add_event(base, slot(0, m + reach), reach - near, leaver, 1)
                    elif m > 0:
                        add_event(base, slot(0, m - reach - 1), reach - near, value, 0)
                        if wp.static(DELAY):
                            add_event(base, slot(0, m + reach), reach - near, leaver, 1)
        # the anchor's parts summed over the block: the warp's by shuffles, the warps' in order
        for round in range(SCAN_ROUNDS):
            mask = 1 << round
            count += shuffle_xor(count, mask)
            offsets += shuffle_xor(offsets, mask)
            level += shuffle_xor_float(level, mask)
        if in_warp == 0:
            set_shared_int64(shared, ANCHOR + 3 * warp, count)
            set_shared_int64(shared, ANCHOR + 3 * warp + 1, offsets)
            set_shared_float(shared, ANCHOR + 3 * warp + 2, level)
        sync_block()
        anchor = state4()
        anchor_level = wp.float64(0.0)
        for w in range(WARPS):
            anchor = anchor + state4(shared_int64(shared, ANCHOR + 3 * w), shared_int64(shared, ANCHOR + 3 * w + 1),
                                     wp.int64(0), wp.int64(0))
            anchor_level += shared_float(shared, ANCHOR + 3 * w + 2)
        if lane == 0:
            for q in range(4):
                set_shared_int64(shared, 4 * WARPS + q, anchor[q])

        chunk = int(0)
        head = int(0)  # the ring bin of the chunk's first step
        upcoming = entering_heights(row, first + s_begin + outer, lane, n)
        for c0 in range(first + s_begin, first + s_end, T):
            # 1. events of the chunk's entering springs (with the delay line also their leaving
            # events), then of its leaving springs (without it)
            for side in range(wp.static(1 if DELAY else 2)):
                loaded = upcoming
                if side == 0:  # the next chunk's entering springs load while this chunk runs (none after the last)
                    upcoming = entering_heights(row, wp.where(c0 + T < first + s_end, c0 + T + outer, n), lane, n)
                else:
                    loaded = entering_heights(row, c0 - near - 1, lane, n)
                for q in range(S):
                    level_i = loaded[q] + d
                    reach = reach_guessed(level_i, curvature, inverse_curvature)
                    if reach >= 0:
                        value = spring_value(level_i, reach, curvature, scale)
                        if side == 0:
                            entry = outer + q * BD + lane - reach
                            add_event(base, slot(head, entry), reach - near, value, 0)
                            if wp.static(DELAY):
                                add_event(base, slot(head, entry + 2 * reach + 1), reach - near,
                                          leaving_value(value, reach, unit), 1)
                        else:
                            add_event(base, slot(head, q * BD + lane + reach - near), reach - near,
                                      leaving_value(value, reach, unit), 1)
            sync_block()
            # 2. this lane's bins: read, compose into one map
            own = state4()
            for q in range(S):
                own = step_bin(own, base, slot(head, lane * S + q), near)
            own_map = step_map(own[0], own[1], own[2], own[3])
            # inclusive scan of the lanes' maps within the warp
            inclusive = own_map
            for round in range(SCAN_ROUNDS):
                delta = 1 << round
                below = step_map(shuffle_up(inclusive[0], delta), shuffle_up(inclusive[1], delta),
                                 shuffle_up(inclusive[2], delta), shuffle_up(inclusive[3], delta))
                if in_warp >= delta:
                    inclusive = then_map(below, inclusive, wp.int64(delta * S))
            before = step_map(shuffle_up(inclusive[0], 1), shuffle_up(inclusive[1], 1),
                              shuffle_up(inclusive[2], 1), shuffle_up(inclusive[3], 1))
            if in_warp == WARP - 1:
                for q in range(4):
                    set_shared_int64(shared, 4 * warp + q, inclusive[q])
            sync_block()
            parity = 4 * WARPS + 4 * (chunk % 2)
            state = state4(shared_int64(shared, parity), shared_int64(shared, parity + 1),
                           shared_int64(shared, parity + 2), shared_int64(shared, parity + 3))
            for w in range(WARPS):
                if w < warp:
                    state = apply_map(state, step_map(shared_int64(shared, 4 * w), shared_int64(shared, 4 * w + 1),
                                                      shared_int64(shared, 4 * w + 2),
                                                      shared_int64(shared, 4 * w + 3)), wp.int64(K_WARP))
            if in_warp > 0:
                state = apply_map(state, before, wp.int64(in_warp * K_LANE))
            # 3. the lane's steps again, from the bins read a second time: each bin's force goes
            # into its first two words (its other two cleared), and the warp then writes its
            # steps' forces out in order, adjacent lanes to adjacent steps, clearing those words
            # (a lane storing its own S consecutive steps would write 8 bytes of each 32-byte
            # sector a store)
            for q in range(S):
                at = slot(head, lane * S + q)
                state = step_bin(state, base, at, near)
                u_total = wp.float64(0.0)  # no spring in contact: exactly no force
                if state[0] != wp.int64(0):
                    u_total = anchor_level + curvature * wp.float64(state[2]) + wp.float64(state[3]) * inverse_scale
                set_shared_float_words(base, at, PADDED, k_spring * u_total - offset)
                set_shared_int(base, 2 * PADDED + at, 0)
                set_shared_int(base, 3 * PADDED + at, 0)
            sync_warp()
            for q in range(S):
                ahead = (lane - in_warp) * S + q * WARP + in_warp  # the warp's steps, lane by lane
                at = slot(head, ahead)
                s = c0 - first + ahead
                if s < s_end:
                    store_float(forces, s, shared_float_words(base, at, PADDED))
                set_shared_int(base, at, 0)
                set_shared_int(base, PADDED + at, 0)
            if lane == BD - 1:
                next_parity = 4 * WARPS + 4 * ((chunk + 1) % 2)
                for q in range(4):
                    set_shared_int64(shared, next_parity + q, state[q])
            sync_block()  # this chunk's bins cleared before the next chunk's events reach them
            chunk += 1
            head += T
            if head >= RING:
                head -= RING

    return contact_force_stream
