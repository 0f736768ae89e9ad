"""Sweep, exact in O(n) at fixed indentation (physics.md section 4; not in the thesis).

With ``curvature = dx^2 / R`` spring i touches the wheel centred on spring c iff
``|i - c| <= M_i``, M_i the largest integer m >= 0 with ``h_i + d - curvature m^2 > 0``
(none if ``h_i + d <= 0``): M_i is :func:`reach_strict` of the level ``h_i + d``, the same
floating-point test ``fl(h_i + d) > fl(fl(curvature m) m)`` that decides ``max(u, 0) > 0`` in
the direct sum's ``spring_sum`` (a fused multiply-add there can move the decision only for
``|u|`` within an ulp of the level, where the spring adds nothing measurable). So spring i is in
contact for the wheel positions ``c in [i - M_i, i + M_i]`` and the force (eq 10-12)

    F(c) = k ( sum_{C(c)} h_i + N(c) d - curvature sum_{C(c)} (i - c)^2 ),   C(c) = {i : |i - c| <= M_i}

follows from four totals over C(c): the count N, sum h, and, with offsets ``m = i - c0`` from a
fixed origin c0, ``P1 = sum m`` and ``P2 = sum m^2``, since ``sum (i - c)^2 = P2 - 2 t P1 + t^2 N``
for ``t = c - c0`` (exact integers). Each spring changes them twice: it enters at
``c = i - M_i`` and leaves after ``c = i + M_i``.

Three forms of the same sweep:

* **stream** (:mod:`mdroll.kernels.sweep_stream`, CUDA's default): a block sweeps a long
  segment of a row chunk by chunk, carrying its totals and its pending events from chunk to
  chunk, so that no chunk re-anchors and each spring is read once (with its delay line; else once
  entering and once leaving);
* **tiles** (:func:`sweep_kernel`, CUDA, the default before the stream): the steps of a tile
  are the lanes of a block, which scatter the events and scan them together (below), each tile
  from its own anchor;
* **sequential** (:data:`contact_force_sequential`, the CPU, where Warp runs one lane a thread):
  each thread sweeps a chunk of consecutive steps in order, carrying the totals from step to
  step and the events pending for the next ``band`` steps in a ring (see its docstring).

All equal the direct sum to rounding; on an H200 the sequential form, one lane a chunk, took
9.5 ms against the tiles' 9.6 at thesis scale and lost more under refinement (its ring, ``band``
slots a lane, leaves fewer lanes resident as the band grows), while on one CPU core it takes
~18-23 ns a step against the tiles' ~32 (docs/performance.md).

Tiles (per block: one row and a tile of T consecutive steps, ``c0 = first + tile T``):

1. *Anchor at c0*: the springs with ``curvature m^2 < d + min h`` (the row's bounds) touch
   whatever h is: the core ``|m| <= core``, a closed form (count, prefix sums S_j of eq 18,
   ``sum m^2``), as in the tree's kernel; each of the ambiguous band springs
   (``core < |m| <= outer``, ``outer`` the M of the row's highest spring) that touches adds
   itself to bin 0.
2. *Events in the tile*: each spring whose entry ``i - M_i`` or exit ``i + M_i + 1`` falls in
   ``(c0, c0 + T)`` adds itself to the bin of that step (springs ``c0 + 1 + core ..
   c0 + T - 1 + outer`` enter, ``c0 - outer .. c0 + T - 2 - core`` leave: ``T + outer - core``
   each), by a block-level scatter into shared memory (``wp.tile_scatter_add``, then a
   barrier). A lane loads ``loads`` entering and as many leaving springs before it scatters
   them, so that on CUDA several loads are in flight between two barriers.
3. *Scan*: each lane turns its ``T / block_dim`` consecutive bins into changes of the four
   totals, keeps them in registers (up to 16 bins a lane) and sums them; a Hillis-Steele scan
   over the lanes' sums (ping-pong shared tiles, log2(block_dim) barriers) gives each lane the
   totals before its bins; the lane runs through its steps, stores ``F - offset`` into a shared
   tile by address (Warp's tile element assignment would add a barrier each), and after one
   barrier the block writes the tile out in order, adjacent lanes to adjacent steps
   (coalesced).

A bin holds nine int32 sums, so that every scatter is a native shared-memory atomic add (the
sm_90 SASS of int64 or float64 atomic adds on shared memory is a compare-and-swap loop,
``ATOMS.CAST.SPIN.64``; the first version, on int64 totals, took 30 ms on an H200 at thesis
scale): the entries' and exits' counts and lags (a spring's reach less the tile's certain core,
``0 <= lag <= band = outer - max(core, 0)``), the squared lags in two 16-bit limbs, and the
heights as the fixed point ``round(h scale)``, ``scale = 2^46 / max |h|`` of the row, in three
limbs (entries minus exits). Springs that share a bin have distinct lags, so no sum can pass
2^31 while ``band <= MAX_BAND`` (16383; the launcher checks). Nine words a bin is an odd
stride, and each lane's bins are followed by one bin of padding: neither the lanes' scatter
into consecutive bins nor their strided reads of their own bins meet a bank twice. The scan
rebuilds the changes in int64, exactly, so the result does not depend on the order of the
atomic adds or of the scan (deterministic, the same for any block_dim); the one float64 total
is the core's prefix-sum difference, and no rounding accumulates along the tile. The fixed
point rounds each height by at most ``max |h| 2^-47`` (~2e-20 m at the defaults, against the
~7e-14 m of 1e-12 F_N).

Work per step: ``2 (T + outer - core) / T`` spring reads, each with one reach (a float32
square root as first guess, made exact by float64 tests) and at most one scatter of nine
atomics, plus ``2 (outer - core) / T`` for the anchor and ``1 / T`` of the closed form; O(1)
per step and per spring for ``T >> outer - core`` (the launcher grows T with the band), so
O(n) per line at any resolution.

Floor (300 x 2^20 steps, float64): each spring is read from memory once (8 B; its second read,
as an exit ``2 M ~ 2000`` springs later, is in a tile of the same row that runs at about the
same time, an L2 hit) and each force written once (8 B): 16 B a step, 5.0 GB, 1.27 ms at the
H200's 3.96 TB/s, the same bytes as the edge kernel (eq 49: one prefix read and one write a
step), which takes 2.55 ms. The arithmetic is ~2.2 reaches (~12 float64 operations each) and
~2.2 x 9 int32 shared-memory atomics a step (~0.3 ms of the H200's float64 rate, ~0.6 ms of its
shared-memory wavefronts at one a bank-conflict-free atomic). At T = 512 and 128 lanes a tile
passes ~22 barriers (5 scatter rounds of two, 1 anchor, 7 scan, 1 after the forces' stores,
the zeroing): the ``loads`` batching and 6 resident blocks a multiprocessor (36 KiB of shared
memory and 80 registers a lane, ptxas for sm_90) are there to hide the latency between them.
(Atomic adds without a barrier each, one barrier after all of them, measured slower: 9.1 ms
against 8.8 on an H200.)
The build adds the row bounds (one pass over the lines, ~0.65 ms at 3.96 TB/s) to the prefix
sums that the edge kernel reads too.

Sequential (one thread: one row and a chunk of consecutive steps): with ``V = sum (h_i -
curvature m^2)`` and ``P = sum m`` over the contact set, m the offsets from the wheel, the force
is ``F = k (V + N d)`` and one step moves every offset by -1:
``V(c + 1) = V(c) + curvature (2 P - N)``, ``P(c + 1) = P - N``, before the springs that enter
or leave at c + 1 change the totals. At step c the thread reads spring ``c + outer`` (the last
that can enter at c; it enters within ``band = outer - max(core, 0)`` steps) and spring
``c - max(core, 0) - 1`` (the first whose exit can fall at c; it leaves within ``band`` steps),
records each event in the ring slot of the step it happens at, then applies and clears the slot
of step c. The chunk starts from the same anchor as a tile. N and P are exact integers; V
carries one rounding a step (~1e-17 m at the defaults) and restarts from the anchor every chunk.
"""

import functools

import warp as wp

from .common import Contact, full_contact_sum, reach_strict, spring_sum, sum_of_squares
from .dynamics import coupled_dynamics

#: A height (m) no indenter reaches: a spring beyond the line, with reach -1.
NO_LEVEL = wp.constant(wp.float64(-1.0e300))

#: The four exact totals of a contact set or a change of it: (count, sum round(h scale),
#: sum m, sum m^2), m the offset from the tile's first step.
totals4 = wp.types.vector(length=4, dtype=wp.int64)

#: A bin's int32 sums, nine (an odd number of words: lanes that scatter into consecutive bins
#: meet no shared-memory bank twice): the entries' and the exits' counts and lags, then the
#: squared lags (signed: entries minus exits) in two 16-bit limbs, and the heights' fixed point
#: (entries minus exits) in 16, 16 and the remaining bits.
bin9 = wp.types.vector(length=9, dtype=wp.int32)

#: The widest band (springs a side whose contact at a tile's first step is uncertain) for which
#: no int32 sum of a bin can overflow: a bin's springs have distinct lags <= band, and bin 0
#: takes up to 2 (band + 1) of them, each limb below 2^16.
MAX_BAND = 16383

#: Fixed-point heights stay below 2^46 (the top limb then below 2^14).
FIXED_RANGE = wp.constant(wp.float64(2.0**46))
LIMB = wp.constant(wp.int64(0xFFFF))


@wp.func_native("""((double*)shared)[i] = value;""")
def shared_store(shared: wp.uint64, i: int, value: wp.float64):
    """Store one float64 in shared memory by its address, without Warp's barrier after a tile
    element's assignment."""
    ...


@wp.func_native("""
#if defined(__CUDA_ARCH__)
__syncthreads();
#else
WP_TILE_SYNC();
#endif
""")
def sync_block():
    """A block's barrier (``__syncthreads`` on CUDA, Warp's CPU block barrier otherwise)."""
    ...


@wp.func
def fixed_scale(bounds: wp.vec2d) -> wp.float64:
    """The fixed-point scale (1/m) of a row of bounds ``(min h, max h)`` (m): ``2^46 / max |h|``."""
    largest = wp.max(wp.abs(bounds[0]), wp.abs(bounds[1]))
    if largest == wp.float64(0.0):
        return wp.float64(1.0)  # a flat line: every height is 0
    return FIXED_RANGE / largest


@wp.func
def event(h: wp.float64, lag: int, scale: wp.float64, leaving: int, sign: int) -> bin9:
    """``sign`` times the bin record of one spring of lag ``lag`` (its reach less the tile's
    certain core, 0 <= lag <= band) entering (``leaving`` 0) or leaving (1)."""
    fixed = wp.int64(wp.round(h * scale))
    square = lag * lag
    entering = sign * (1 - leaving)
    exiting = sign * leaving
    flip = entering - exiting  # exits enter the signed sums negated
    return bin9(entering, exiting, entering * lag, exiting * lag, flip * (square & 0xFFFF), flip * (square >> 16),
                flip * wp.int32(fixed & LIMB), flip * wp.int32((fixed >> wp.int64(16)) & LIMB),
                flip * wp.int32(fixed >> wp.int64(32)))


@wp.func
def bin_change(record: bin9, t: int, near: int) -> totals4:
    """The change of the totals at step t of the tile from the springs of one bin: entries sit
    at ``m = t + near + lag``, exits at ``m = t - near - 1 - lag`` (eq 10-12, exact integers)."""
    enter = wp.int64(t + near)
    leave = wp.int64(t - near - 1)
    entering = wp.int64(record[0])
    leaving = wp.int64(record[1])
    lag_in = wp.int64(record[2])
    lag_out = wp.int64(record[3])
    squares = wp.int64(record[4]) + (wp.int64(record[5]) << wp.int64(16))
    heights = wp.int64(record[6]) + (wp.int64(record[7]) << wp.int64(16)) + (wp.int64(record[8]) << wp.int64(32))
    two = wp.int64(2)
    return totals4(
        entering - leaving,
        heights,
        entering * enter + lag_in - leaving * leave + lag_out,
        entering * enter * enter + two * enter * lag_in - leaving * leave * leave + two * leave * lag_out + squares,
    )


@wp.func
def force_of_totals(
    totals: totals4,
    core_heights: wp.float64,
    t: int,
    d: wp.float64,
    curvature: wp.float64,
    inverse_scale: wp.float64,
    k_spring: wp.float64,
    offset: wp.float64,
) -> wp.float64:
    """``F - offset`` (N) for the wheel t steps past the tile's origin: eq 10-12 summed over the
    contact set, ``k (sum h + N d - curvature (P2 - 2 t P1 + t^2 N))``, with ``core_heights`` the
    core's sum of h (m) and the rest of sum h in ``totals[1]`` (units of 1 / scale m)."""
    shift = wp.int64(t)
    squares = totals[3] - wp.int64(2) * shift * totals[2] + shift * shift * totals[0]
    heights = core_heights + wp.float64(totals[1]) * inverse_scale
    return k_spring * (heights + wp.float64(totals[0]) * d - curvature * wp.float64(squares)) - offset


@functools.cache
def sweep_kernel(tile_steps: int, block_dim: int, loads: int = 1):
    """The sweep kernel for tiles of ``tile_steps`` steps and blocks of ``block_dim`` lanes
    (``tile_steps`` a multiple of ``block_dim``, ``block_dim`` a power of two; block_dim 1 on
    the CPU), each lane loading ``loads`` entering and as many leaving springs before it
    scatters them (on CUDA their loads are then in flight together). Exact for rows whose
    band is at most MAX_BAND springs (module docstring). Launched by
    ``wp.launch_tiled`` over ``(R, ceil(steps / tile_steps))``. It takes the lines' arrays one by
    one, not as the coupled step's :class:`SweepLines`: with the struct ptxas gave it 84
    registers a lane against 80 (one block fewer a multiprocessor), and it took 9.71 ms against
    8.80 at thesis scale on an H200."""
    if block_dim < 1 or block_dim & (block_dim - 1) or tile_steps % block_dim or loads < 1:
        raise ValueError(f"tile_steps = {tile_steps} must be a multiple of block_dim = {block_dim}, a power of two; "
                         f"loads = {loads} >= 1")
    T = tile_steps
    BD = block_dim
    S = T // BD  # bins a lane scans
    LOG_S = S.bit_length() - 1
    # bin t lives at t + (t >> LOG_S): one bin of padding after each lane's bins, so that the lanes'
    # strided reads of their own bins fall in different banks
    PADDED = T + BD
    LOADS = loads
    SCAN_ROUNDS = BD.bit_length() - 1
    heights_batch = wp.types.vector(length=LOADS, dtype=wp.float64)
    # a lane's S bin changes kept in registers between the two scan passes (when S is small
    # enough for its loops to unroll), instead of computed twice
    CACHED = S <= 16
    lane_changes = wp.types.matrix(shape=(S, 4), dtype=wp.int64)

    @wp.func_native("""return (uint64_t)(&memory.data(0));""")
    def forces_address(memory: wp.tile(dtype=wp.float64, shape=(PADDED,), storage="shared")) -> wp.uint64: ...

    @wp.kernel(module="unique", enable_backward=False)
    def contact_force_sweep(
        lines: wp.array2d(dtype=wp.float64),
        prefix: wp.array2d(dtype=wp.float64),
        bounds: wp.array(dtype=wp.vec2d),
        n: int,
        first: int,
        steps: int,
        d: wp.float64,
        curvature: wp.float64,
        k_spring: wp.float64,
        offset: wp.float64,
        force: wp.array2d(dtype=wp.float64),
    ):
        """``force[r, s] = F - offset`` (N): F (eq 10-12) with the wheel at spring ``first + s``
        of row r, indentation d (m), for the steps s of this block's tile."""
        r, tile, lane = wp.tid()
        s0 = tile * T
        c0 = first + s0
        box = bounds[r]
        core = reach_strict(d + box[0], curvature)  # every spring reaches this far (-1: none surely)
        outer = reach_strict(d + box[1], curvature)  # no spring reaches farther
        near = wp.max(core, 0)
        scale = fixed_scale(box)
        row = lines[r]
        bins = wp.tile_zeros(shape=PADDED, dtype=bin9, storage="shared")

        # 1. the band springs in contact at c0 go to bin 0: right c0+core+1 .. c0+outer as
        # entries (m = near + lag), left c0-outer .. c0-near-1 as exits (m = -near-1-lag)
        # negated, so that they add (the core's closed form is added below)
        right = wp.max(outer - core, 0)
        band = right + wp.max(outer - near, 0)
        for start in range(0, band, BD):
            j = start + lane
            m = core + 1 + j
            side = int(0)  # 0: right, an entry; 1: left, an exit
            lag = m - near
            if j >= right:
                m = -outer + j - right
                side = 1
                lag = -near - 1 - m
            record = bin9()
            touches = False
            if j < band and c0 + m >= 0 and c0 + m < n:
                h = row[c0 + m]
                touches = wp.abs(m) <= reach_strict(h + d, curvature)
                if touches:
                    record = event(h, lag, scale, side, 1 - 2 * side)
            wp.tile_scatter_add(bins, 0, record, touches)

        # 2. entries (at step i - M) and exits (at i + M + 1) inside the tile: the lane loads
        # its LOADS entering and LOADS leaving candidates first, so that their loads are in
        # flight together, then scatters them
        spread = wp.max(T - 1 + outer - near, 0)
        for start in range(0, spread, BD * LOADS):
            entering = heights_batch()
            leaving = heights_batch()
            for u in range(LOADS):
                j = start + u * BD + lane
                i = c0 + 1 + near + j
                entering[u] = NO_LEVEL
                if j < spread and i < n:
                    entering[u] = row[i]
                i = c0 - outer + j
                leaving[u] = NO_LEVEL
                if j < spread and i >= 0 and i < n:
                    leaving[u] = row[i]
            for u in range(LOADS):
                m = 1 + near + start + u * BD + lane  # the entering spring's offset from c0
                reach = reach_strict(entering[u] + d, curvature)
                at = m - reach
                enters = reach >= 0 and at >= 1 and at < T
                record = bin9()
                if enters:
                    record = event(entering[u], reach - near, scale, 0, 1)
                wp.tile_scatter_add(bins, at + (at >> LOG_S), record, enters)
                m = m - 1 - near - outer  # the leaving spring's
                reach = reach_strict(leaving[u] + d, curvature)
                at = m + reach + 1
                leaves = reach >= 0 and at >= 1 and at < T
                record = bin9()
                if leaves:
                    record = event(leaving[u], reach - near, scale, 1, 1)
                wp.tile_scatter_add(bins, at + (at >> LOG_S), record, leaves)

        # 3. scan: this lane's bins lane*S .. lane*S+S-1, after the totals of the lanes before
        first_bin = lane * S
        own = totals4()
        changes = lane_changes()
        for k in range(S):
            change = bin_change(bins[first_bin + lane + k], first_bin + k, near)
            if wp.static(CACHED):
                for q in range(4):
                    changes[k, q] = change[q]
            own = own + change
        inclusive = own
        ping = wp.tile_zeros(shape=BD, dtype=totals4, storage="shared")
        pong = wp.tile_zeros(shape=BD, dtype=totals4, storage="shared")
        ping[lane] = inclusive
        shift = int(1)
        for level in range(SCAN_ROUNDS):
            if level % 2 == 0:
                if lane >= shift:
                    inclusive = inclusive + ping[lane - shift]
                pong[lane] = inclusive
            else:
                if lane >= shift:
                    inclusive = inclusive + pong[lane - shift]
                ping[lane] = inclusive
            shift *= 2
        running = inclusive - own
        # the core at c0, |m| <= core: count, sum m = 0, sum m^2, and its sum of h from the
        # prefix sums (eq 18), the one float64 total
        core_heights = wp.float64(0.0)
        if core >= 0:
            running = running + totals4(wp.int64(2 * core + 1), wp.int64(0), wp.int64(0),
                                        wp.int64(sum_of_squares(-core, core)))
            core_heights = prefix[r, c0 + core + 1] - prefix[r, c0 - core]
        inverse_scale = wp.float64(1.0) / scale
        forces = wp.tile_zeros(shape=PADDED, dtype=wp.float64, storage="shared")
        lane_forces = forces_address(forces)  # each lane writes its own steps: no barrier until all are written
        for k in range(S):
            t = first_bin + k
            if wp.static(CACHED):
                running = running + totals4(changes[k, 0], changes[k, 1], changes[k, 2], changes[k, 3])
            else:
                running = running + bin_change(bins[t + lane], t, near)
            shared_store(lane_forces, t + lane,
                         force_of_totals(running, core_heights, t, d, curvature, inverse_scale, k_spring, offset))
        sync_block()
        # written back in order, adjacent lanes to adjacent steps (coalesced)
        for k in range(S):
            t = k * BD + lane
            if s0 + t < steps:
                force[r, s0 + t] = forces[t + (t >> LOG_S)]

    return contact_force_sweep


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
    the certain core ``|m| <= reach(d + min h)`` in closed form (eq 18-20, as a tile's anchor),
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
