"""Coupled wheel dynamics with the semi-implicit (symplectic) Euler step (physics.md section 5, eq 13).

Time is sequential per realization; on CUDA one warp per realization shares each step's spring
sum (:data:`COUPLED_LANES` lanes, summed by warp shuffles), several realizations a block.
The decoupled response (section 5.1) is linear and needs no time loop: kernels/moments.py.
Semi-implicit Euler: ``v += dt a(y)`` first, then ``y += dt v`` with the new v; plain forward
Euler grows the oscillation's amplitude by exp(N (omega_0 dt)^2 / 2) over N steps (docs/physics.md
section 5: ~35 % in amplitude, ~83 % in energy over ~10^6 steps at the defaults). Forward Euler
(``y += dt v`` with the old v, then ``v += dt a``) is the thesis's scheme ("Euler", section 3.4):
it is kept, as a compile-time variant of the same kernel (:func:`with_integrator`), only to test
whether it explains the thesis's Figure 11 (mdroll study coupling); every amplitude grows by
``sqrt(1 + (omega dt)^2)`` a step under it.

:func:`coupled_dynamics` makes the kernel of one force algorithm from its lane force and its
row set-up (``wp.func`` functions), compiled apart (``wp.static``): each algorithm's kernel module
declares its own. The contact point is a compile-time choice of the same kernel: the rigid rail
of eq 13, or a modal state space (:class:`~mdroll.kernels.modal.Modes`) stepped with the wheel
(:func:`coupled_track`).
"""

from typing import Any

import warp as wp

from .common import Contact
from .intrinsics import (PipelineSums, backoff, fence_block, pipelined_sums, row_address, set_shared_pair,
                         set_shared_volatile, shared_pair, shared_volatile, store_float, sync_block, sync_warp,
                         warp_sum_float)
from .modal import ModalComing, Modes, held_coefficients, modal_update

#: Lanes sharing one realization in the coupled dynamics on CUDA: one whole warp, so that a step's
#: sum is a butterfly of warp shuffles. Warp runs tiles with one thread on the CPU: one lane there.
COUPLED_LANES = 32

#: Realizations (warps) a block on CUDA (the choice: docs/performance.md, "Coupled mode"). Any
#: count of realizations runs: the warps past the last realization of the last block return at
#: once.
COUPLED_WARPS = 4

#: The time steps of eq 13: the semi-implicit (symplectic) Euler step, and forward Euler, the
#: thesis's scheme, for the coupling study only (module docstring).
INTEGRATORS = ("semi-implicit", "forward-euler")

#: Helper warps a realization on CUDA in the kernels whose steps are prepared ahead
#: (:func:`coupled_dynamics`'s ``prepared``): with the stepping warp, a block of four.
COUPLED_HELPERS = 3

#: Registers a lane of the helped kernels may use: low enough for the blocks of a batch that
#: leaves the GPU idle (:data:`COUPLED_HELPERS`) to fit its multiprocessors at once, three blocks
#: of four warps (65536 registers a multiprocessor / 384 lanes, in steps of 8).
HELPED_REGISTERS = 168

#: Steps ahead of the stepping warp that a step's force is prepared, from the indentation then
#: and the two steps before; the first ``PREPARED_AHEAD + 2`` steps are summed directly.
PREPARED_AHEAD = 16

#: Consecutive steps one build prepares (the algorithm's ``prepare`` returns their slots), each
#: one step further ahead than the one before: a helper's builds start this many steps apart.
#: A power of two up to 4 (:func:`warp_sums`; one byte a step in a 32-bit reduction).
PREPARED_STEPS = 4

#: Steps a block's shared ring holds (a power of two, at least PREPARED_AHEAD + PREPARED_STEPS:
#: a build's last step is then never where the stepping warp has yet to read): the indentations,
#: each with its step (plus one, 0 for none), the prepared steps (8 words each) and the step
#: each holds (plus one).
RING = 32
RING_WORDS = 11 * RING

#: A prepared step, as the algorithm's ``prepare`` returns it and its ``prepared_force`` reads it.
PreparedSlot = wp.types.vector(length=8, dtype=wp.float64)

#: A prepared step as the stepping warp uses it (:func:`linear_step`).
PreparedLine = wp.types.vector(length=6, dtype=wp.float64)

#: The prepared steps of one build, one a row (:data:`PREPARED_STEPS`).
PreparedSlots = wp.types.matrix(shape=(PREPARED_STEPS, 8), dtype=wp.float64)

#: One float64 for each step of a build.
PreparedSums = wp.types.vector(length=PREPARED_STEPS, dtype=wp.float64)

# (lines_type, lane_force, row_setup) of each kernel made, and every kernel made, by its arguments
_MADE_FROM: dict = {}
_KERNELS: dict = {}


@wp.func_native("""
#if defined(__CUDA_ARCH__)
constexpr int P = sizeof(values.c) / sizeof(values.c[0]);
const unsigned lane = threadIdx.x & 31u;
double v[P];
#pragma unroll
for (int i = 0; i < P; ++i) v[i] = values.c[i];
int mask = 16;
#pragma unroll
for (int width = P; width > 1; width >>= 1, mask >>= 1) {
    const bool upper = (lane & mask) != 0u;
#pragma unroll
    for (int i = 0; i < width / 2; ++i) {
        const double send = upper ? v[i] : v[i + width / 2];
        const double keep = upper ? v[i + width / 2] : v[i];
        v[i] = keep + __shfl_xor_sync(0xffffffffu, send, mask);
    }
}
#pragma unroll
for (; mask > 0; mask >>= 1) v[0] += __shfl_xor_sync(0xffffffffu, v[0], mask);
#pragma unroll
for (int i = 0; i < P; ++i) {
    int source = 0, level = 16;
#pragma unroll
    for (int width = P; width > 1; width >>= 1, level >>= 1) source += (i & (width / 2)) ? level : 0;
    values.c[i] = __shfl_sync(0xffffffffu, v[0], source);
}
#endif
return values;
""")
def warp_sums(values: PreparedSums) -> PreparedSums:
    """Each of the :data:`PREPARED_STEPS` float64 summed over the 32 lanes of the warp, in every
    lane (CUDA; the values themselves on the CPU, where a block is one lane; every lane of the
    warp must call): the first levels of the butterfly halve the values a lane carries (a lane
    sends the half its partner keeps), the rest add one, and each sum is broadcast from a lane
    that holds it: a shuffle and an add a level, and one a sum to gather."""
    ...


@wp.func_native("""return (uint64_t)(&ring.data(0));""")
def ring_address(ring: wp.tile(dtype=wp.float64, shape=(RING_WORDS,), storage="shared")) -> wp.uint64:
    """The address of a block's shared ring."""
    ...


@wp.func
def published_slots(base: wp.uint64, k: int, slots: PreparedSlots):
    """Writes the prepared steps k, k + 1, ... of a build into the ring, then (after a fence) the
    steps they hold."""
    for j in range(PREPARED_STEPS):
        at = (k + j) & (RING - 1)
        for i in range(8):
            set_shared_volatile(base, 2 * RING + 8 * at + i, slots[j, i])
    fence_block()
    for j in range(PREPARED_STEPS):
        set_shared_volatile(base, 10 * RING + ((k + j) & (RING - 1)), wp.float64(k + j + 1))


@wp.func
def awaited_slot(base: wp.uint64, s: int) -> PreparedSlot:
    """The prepared step s from the ring, once a helper has written it (its reads wait on the
    step's, which its writer wrote after them)."""
    at = s & (RING - 1)
    while shared_volatile(base, 10 * RING + at) != wp.float64(s + 1):
        backoff()
    slot = PreparedSlot()
    for i in range(8):
        slot[i] = shared_volatile(base, 2 * RING + 8 * at + i)
    return slot


@wp.func
def linear_step(slot: PreparedSlot, contact: Contact, F_N: wp.float64, inv_mass: wp.float64) -> PreparedLine:
    """A prepared step's force and the wheel's acceleration as linear functions of d where they
    are (the slot ready, no spring open): ``(lo, hi, k N, k T, k N / m, (F_N + k T) / m)`` for F =
    k N d - k T and d'' = (F_N + k T) / m - (k N / m) d over ``lo <= d <= hi``, an empty window
    (lo infinite) where they are not; worked out before the step, whose chain is then one
    operation from d to d''."""
    stiffness = contact.k_spring * slot[3]
    offset = contact.k_spring * slot[4]
    linear = slot[2] > wp.float64(0.0) and slot[5] == wp.float64(wp.inf)
    return PreparedLine(wp.where(linear, slot[0], wp.float64(wp.inf)), slot[1], stiffness, offset,
                        stiffness * inv_mass, (F_N + offset) * inv_mass)


@wp.func
def peeked_slot(base: wp.uint64, s: int):
    """The prepared step s as the ring holds it now, and whether a helper has written it (its step
    read first, then its words): read the step before it is needed, so that its loads wait on
    nothing and stand in no step's chain. The words are those the step vouches for because a
    warp's shared-memory loads complete in the order it issues them (an acquire load would say so
    in the memory model's terms, on the step's chain); the CUDA tests hold it to 1e-12 F_N."""
    at = s & (RING - 1)
    written = shared_volatile(base, 10 * RING + at) == wp.float64(s + 1)
    slot = PreparedSlot()
    for i in range(6):  # those that linear_step reads
        slot[i] = shared_volatile(base, 2 * RING + 8 * at + i)
    return slot, written


@wp.func
def published_depth(base: wp.uint64, s: int, d: wp.float64):
    """Writes step s's indentation d (m) into the ring with its step (plus one), in one write."""
    set_shared_pair(base, s & (RING - 1), d, wp.float64(s + 1))


@wp.func
def awaited_depths(base: wp.uint64, s: int) -> wp.vec3d:
    """The indentations (m) of steps s, s - 1 and s - 2 from the ring, once the stepping warp has
    published them (the three read together)."""
    now = shared_pair(base, s & (RING - 1))
    before = shared_pair(base, (s - 1) & (RING - 1))
    earlier = shared_pair(base, (s - 2) & (RING - 1))
    while now[1] != wp.float64(s + 1) or before[1] != wp.float64(s) or earlier[1] != wp.float64(s - 1):
        backoff()
        now = shared_pair(base, s & (RING - 1))
        before = shared_pair(base, (s - 1) & (RING - 1))
        earlier = shared_pair(base, (s - 2) & (RING - 1))
    return wp.vec3d(now[0], before[0], earlier[0])


@wp.func
def row_index(lines: Any, r: int, contact: Contact) -> int:
    """The row set-up of an algorithm that keeps nothing of a row over the steps: its index."""
    return r


def coupled_dynamics(lines_type, lane_force, row_setup=row_index, forward_euler: bool = False,
                     modal: bool = False, prepared=None, helped: bool = False) -> wp.Kernel:
    """The eq 13 kernel of the algorithm whose share of a step's force is ``lane_force``.

    ``row_setup(lines: lines_type, r: int, contact: Contact) -> row`` reads, once before the
    steps, what the steps need of row r (default: :func:`row_index`); ``lane_force(lines:
    lines_type, row, c: int, d: wp.float64, contact: Contact, lane: int, lanes: int) ->
    (wp.float64, row)`` returns the part (N) of F(x_w, d) that ``lane`` of ``lanes`` computes
    with the wheel at spring c of the row, indentation d (m), and the row to pass to the next
    step; the parts of all lanes sum to F. ``lines_type``: what the algorithm reads of the
    lines (a ``wp.struct`` or an array). ``forward_euler``: the thesis's forward Euler step
    instead of the semi-implicit one; ``modal``: the contact point moves with a modal state
    space (:func:`coupled_track`); both chosen at compile time (``wp.static``).

    ``prepared``: for an algorithm that can prepare a step's force ahead, the pair ``(prepare,
    prepared_force)``: ``prepare(lines, row, c, ahead: int, d, d1, d2, contact, lane, lanes) ->
    PreparedSlots``, the :data:`PREPARED_STEPS` steps with the wheel at c, c + 1, ... from the
    indentations (m) ``ahead`` steps before the first and the two before that, and
    ``prepared_force(lines, row, slot, c, d, contact, lane, lanes) -> (F, row)``, the whole F in
    every lane. ``helped``: the variant that uses them (:func:`with_helpers`).
    One kernel per set of arguments, made once.
    """
    key = (lines_type, lane_force, row_setup, forward_euler, modal, prepared, helped)
    made = _KERNELS.get(key)
    if made is None:
        made = _KERNELS[key] = _coupled_kernel(*key)
        _MADE_FROM[made] = key
    return made


def with_integrator(kernel: wp.Kernel, integrator: str) -> wp.Kernel:
    """The variant of a kernel of :func:`coupled_dynamics` that steps eq 13 by ``integrator``
    (one of :data:`INTEGRATORS`)."""
    lines_type, lane_force, row_setup, _, modal, prepared, helped = _MADE_FROM[kernel]
    return coupled_dynamics(lines_type, lane_force, row_setup, integrator == INTEGRATORS[1], modal, prepared, helped)


def coupled_track(kernel: wp.Kernel) -> wp.Kernel:
    """The variant of a kernel of :func:`coupled_dynamics` whose contact point moves: the
    indentation is the wheel mass's minus the output of a modal state space (the rail's and a
    modal wheel's receptances) driven by F - F_N."""
    lines_type, lane_force, row_setup, forward_euler, _, prepared, helped = _MADE_FROM[kernel]
    return coupled_dynamics(lines_type, lane_force, row_setup, forward_euler, True, prepared, helped)


def with_helpers(kernel: wp.Kernel) -> wp.Kernel | None:
    """The variant of a kernel of :func:`coupled_dynamics` whose steps are prepared ahead, one
    realization a block: on CUDA the block's first warp steps it and the others (helpers)
    prepare its steps :data:`PREPARED_AHEAD` ahead, through a ring in shared memory; a block of
    one warp (and the CPU's one lane) prepares them itself. None for an algorithm that cannot."""
    lines_type, lane_force, row_setup, forward_euler, modal, prepared, _ = _MADE_FROM[kernel]
    if prepared is None:
        return None
    return coupled_dynamics(lines_type, lane_force, row_setup, forward_euler, modal, prepared, True)


def _coupled_kernel(lines_type, lane_force, row_setup, forward_euler: bool, modal: bool, prepared,
                    helped: bool) -> wp.Kernel:
    prepare, prepared_force = prepared if helped else (None, None)

    @wp.func
    def prepared_step(lines: lines_type, row: Any, base: wp.uint64, s: int, line: PreparedLine, c: int,
                      d: wp.float64, contact: Contact, F_N: wp.float64, inv_mass: wp.float64, lane: int,
                      lanes: int):
        """F (N) and the wheel's acceleration (m/s^2) at indentation d (m) of prepared step s (its
        slot in the ring) and the row for the next step: with d in the window of its
        :func:`linear_step`, one operation from d to the acceleration; else the algorithm's
        ``prepared_force`` of the slot."""
        if line[0] <= d and d <= line[1]:
            return line[2] * d - line[3], line[5] - line[4] * d, row
        slot = PreparedSlot()  # none ready before the first prepared step: the band summed directly
        if s >= PREPARED_AHEAD + 2:
            slot = awaited_slot(base, s)
        F, moved = wp.static(prepared_force)(lines, row, slot, c, d, contact, lane, lanes)
        return F, (F_N - F) * inv_mass, moved

    @wp.kernel(module="unique", enable_backward=False, cuda_max_registers=HELPED_REGISTERS if helped else None)
    def coupled_response(
        lines: lines_type,
        contact: Contact,
        rows: int,
        first: int,
        steps: int,
        d_start: wp.float64,
        F_N: wp.float64,
        inv_mass: wp.float64,
        dt: wp.float64,
        force_offset: wp.float64,
        force: wp.array2d(dtype=wp.float64),
        accel: wp.array2d(dtype=wp.float64),
        modes: Modes,
        state: wp.array2d(dtype=wp.vec2d),
    ):
        """Eq 13: ``m d_w'' = F_N - F(x_w(t), d(t))``, d_w(0) = d_start (d0 in the thesis),
        d_w'(0) = 0, the wheel one spring per step from spring ``first``; semi-implicit Euler
        steps (forward Euler in the ``forward_euler`` variant). The indentation d is d_w on the
        rigid rail; in the ``modal`` variant ``d = d_w - y``, y the output of the modal state
        space ``modes`` (its states ``state[r]``, zero at the start) driven by F - F_N, the force
        of each step held over it (``inv_mass`` 0 holds the mass at d_start: a modal wheel).

        Launched tiled: on CUDA each warp of a block steps one realization (rows past ``rows``
        return), on the CPU each block one. Time is sequential, so the lanes share each step's
        force instead: every lane computes its part (``lane_force``) and its modes, a butterfly
        of shuffles sums the force in every lane, and every lane advances the same state with the
        same arithmetic. What the steps need of the row is read once before them
        (``row_setup``) and passed from step to step. The output y of the next step comes from
        the modes' exact look-ahead (:mod:`mdroll.kernels.modal`): their sums over the lanes
        advance one butterfly level a step beside the force, and the step's chain keeps one
        multiply-add of it. In the ``helped`` variant a block holds one realization: its
        first warp steps it, the steps' forces prepared ahead (``prepare``, :data:`PREPARED_STEPS`
        a build) by the block's other warps in turn, or by the first warp itself in a block of
        one warp, and read from the block's shared ring a step early, so that a step's chain is
        one operation from d to d'' (:func:`linear_step`; ``prepared_force`` outside the slot's
        window); the stepping warp publishes each indentation there, and its lanes store the
        force and acceleration 32 steps at once. Writes ``force = F - force_offset`` (N) and
        ``accel = d_w''`` (m/s^2); steps without contact are those with F = 0.
        """
        block, thread = wp.tid()
        lanes = wp.min(wp.block_dim(), COUPLED_LANES)
        warps = wp.block_dim() // lanes
        r = block * warps + thread // lanes
        if wp.static(helped):
            r = block
        if r >= rows:
            return
        lane = thread % lanes
        row = wp.static(row_setup)(lines, r, contact)
        base = wp.uint64(0)
        if wp.static(helped):
            ring = wp.tile_zeros(shape=RING_WORDS, dtype=wp.float64, storage="shared")
            base = ring_address(ring)
            if thread == 0:
                published_depth(base, 0, d_start)
            sync_block()
            helper = thread // lanes
            if helper > 0:  # prepare the steps past the first, PREPARED_STEPS a build, the helpers in turn
                k = PREPARED_AHEAD + 2 + PREPARED_STEPS * (helper - 1)
                while k < steps:
                    depths = awaited_depths(base, k - PREPARED_AHEAD)
                    slots = wp.static(prepare)(lines, row, first + k, PREPARED_AHEAD, depths[0], depths[1], depths[2],
                                               contact, lane, lanes)
                    if lane == 0:
                        published_slots(base, k, slots)
                    k += PREPARED_STEPS * (warps - 1)
                return
        forces = row_address(force, r)
        accels = row_address(accel, r)
        d_w = d_start
        v = wp.float64(0.0)
        y = wp.float64(0.0)  # the contact point's displacement (m), modal variant
        held = held_coefficients(modes, lane, lanes)  # this lane's first modes
        sums = PipelineSums()  # the modes' sums over the lanes in flight (modal_update)
        coming = ModalComing()  # the parts of the next outputs known so far
        a = wp.float64(0.0)
        ahead = PreparedSlot()  # the next step's prepared slot, read a step early (helped variant)
        ahead_written = bool(False)
        line = PreparedLine()  # this step's linear_step (helped variant; none before the first prepared)
        line[0] = wp.float64(wp.inf)
        kept_force = wp.float64(0.0)  # this lane's step of the batch of `lanes` steps stored at once
        kept_accel = wp.float64(0.0)
        for s in range(steps):
            F = wp.float64(0.0)
            d = d_w
            if wp.static(modal):
                d = d_w - y
            if wp.static(helped):
                if warps == 1:  # no helpers: prepare steps k, k + 1, ... here
                    k = s + PREPARED_AHEAD
                    if k >= PREPARED_AHEAD + 2 and (k - PREPARED_AHEAD - 2) % PREPARED_STEPS == 0 and k < steps:
                        depths = awaited_depths(base, s)
                        slots = wp.static(prepare)(lines, row, first + k, PREPARED_AHEAD, d, depths[1], depths[2],
                                                   contact, lane, lanes)
                        if lane == 0:
                            published_slots(base, k, slots)
                if s >= PREPARED_AHEAD + 2 and not ahead_written:  # not written when read: wait for it
                    line = linear_step(awaited_slot(base, s), contact, F_N, inv_mass)
                ahead, ahead_written = peeked_slot(base, s + 1)  # the next step's, off this step's chain
            if wp.static(modal):
                sums = pipelined_sums(sums)  # a level of each sum in flight, not waiting on this step's force
            if wp.static(helped):
                F, a, row = prepared_step(lines, row, base, s, line, first + s, d, contact, F_N, inv_mass, lane, lanes)
            else:
                part, row = wp.static(lane_force)(lines, row, first + s, d, contact, lane, lanes)
                F = warp_sum_float(part)
            if wp.static(modal):
                y, held, sums, coming = modal_update(modes, state, r, F - F_N, lane, lanes, held, sums, coming)
            if wp.static(helped):  # every lane holds F and a: lane j keeps step j of a batch of `lanes`
                batch = s & (lanes - 1)
                if lane == batch:
                    kept_force = F - force_offset
                    kept_accel = a
                if (batch == lanes - 1 or s == steps - 1) and lane <= batch:
                    store_float(forces, s - batch + lane, kept_force)
                    store_float(accels, s - batch + lane, kept_accel)
            else:
                a = (F_N - F) * inv_mass
                if lane == 0:
                    store_float(forces, s, F - force_offset)
                    store_float(accels, s, a)
            if wp.static(forward_euler):
                d_w += dt * v  # the old velocity (the thesis's scheme)
                v += dt * a
            else:
                v += dt * a
                d_w += dt * v
            if wp.static(helped):  # the next indentation, for the helpers
                if lane == 0:
                    if wp.static(modal):
                        published_depth(base, s + 1, d_w - y)
                    else:
                        published_depth(base, s + 1, d_w)
                sync_warp()
                line = linear_step(ahead, contact, F_N, inv_mass)  # the next step's, off this step's chain

    return coupled_response
