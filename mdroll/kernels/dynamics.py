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
of eq 13, or a modal state space (:class:`Modes`) stepped with the wheel (:func:`coupled_track`).
"""

from typing import Any

import warp as wp

from .common import Contact
from .intrinsics import row_address, store_float, warp_sum_float, warp_sum_float_pair

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

# (lines_type, lane_force, row_setup) of each kernel made, and every kernel made, by its arguments
_MADE_FROM: dict = {}
_KERNELS: dict = {}


@wp.struct
class Modes:
    """The zero-order-hold step of a modal state space (:class:`mdroll.statespace.ModalForm`):
    per mode k, ``q_k <- phi_k q_k + gamma_k u`` (complex) and the output ``y = 2 Re sum_k q_k``;
    ``gain = 2 Re sum_k gamma_k``, the output's step response to u over one step from rest."""

    phi_re: wp.array(dtype=wp.float64)
    phi_im: wp.array(dtype=wp.float64)
    gamma_re: wp.array(dtype=wp.float64)
    gamma_im: wp.array(dtype=wp.float64)
    gain: wp.float64
    n: int


@wp.func
def modal_step(modes: Modes, state: wp.array2d(dtype=wp.vec2d), r: int, u: wp.float64, lane: int, lanes: int):
    """Steps the modes ``lane, lane + lanes, ...`` of realization r (their complex states
    ``state[r, k]``) over one time step under the force u (N), held over the step; returns
    their part of the next step's free output ``2 Re sum_k phi_k q_k`` (m): the parts of all
    lanes sum to the output the modes would give one step later under no force."""
    free = wp.float64(0.0)
    two = wp.float64(2.0)
    for k in range(lane, modes.n, lanes):
        q = state[r, k]
        re = modes.phi_re[k] * q[0] - modes.phi_im[k] * q[1] + modes.gamma_re[k] * u
        im = modes.phi_re[k] * q[1] + modes.phi_im[k] * q[0] + modes.gamma_im[k] * u
        state[r, k] = wp.vec2d(re, im)
        free += two * (modes.phi_re[k] * re - modes.phi_im[k] * im)
    return free


@wp.func
def row_index(lines: Any, r: int, contact: Contact) -> int:
    """The row set-up of an algorithm that keeps nothing of a row over the steps: its index."""
    return r


def coupled_dynamics(lines_type, lane_force, row_setup=row_index, forward_euler: bool = False,
                     modal: bool = False) -> wp.Kernel:
    """The eq 13 kernel of the algorithm whose share of a step's force is ``lane_force``.

    ``row_setup(lines: lines_type, r: int, contact: Contact) -> row`` reads, once before the
    steps, what the steps need of row r (default: :func:`row_index`); ``lane_force(lines:
    lines_type, row, c: int, d: wp.float64, contact: Contact, lane: int, lanes: int) ->
    (wp.float64, row)`` returns the part (N) of F(x_w, d) that ``lane`` of ``lanes`` computes
    with the wheel at spring c of the row, indentation d (m), and the row to pass to the next
    step; the parts of all lanes sum to F. ``lines_type``: what the algorithm reads of the
    lines (a ``wp.struct`` or an array). ``forward_euler``: the thesis's forward Euler step
    instead of the semi-implicit one; ``modal``: the contact point moves with a modal state
    space (:func:`coupled_track`); both chosen at compile time (``wp.static``). One kernel per
    set of arguments, made once.
    """
    key = (lines_type, lane_force, row_setup, forward_euler, modal)
    made = _KERNELS.get(key)
    if made is None:
        made = _KERNELS[key] = _coupled_kernel(*key)
        _MADE_FROM[made] = key
    return made


def with_integrator(kernel: wp.Kernel, integrator: str) -> wp.Kernel:
    """The variant of a kernel of :func:`coupled_dynamics` that steps eq 13 by ``integrator``
    (one of :data:`INTEGRATORS`)."""
    lines_type, lane_force, row_setup, _, modal = _MADE_FROM[kernel]
    return coupled_dynamics(lines_type, lane_force, row_setup, integrator == INTEGRATORS[1], modal)


def coupled_track(kernel: wp.Kernel) -> wp.Kernel:
    """The variant of a kernel of :func:`coupled_dynamics` whose contact point moves: the
    indentation is the wheel mass's minus the output of a modal state space (the rail's and a
    modal wheel's receptances) driven by F - F_N."""
    lines_type, lane_force, row_setup, forward_euler, _ = _MADE_FROM[kernel]
    return coupled_dynamics(lines_type, lane_force, row_setup, forward_euler, True)


def _coupled_kernel(lines_type, lane_force, row_setup, forward_euler: bool, modal: bool) -> wp.Kernel:

    @wp.kernel(module="unique", enable_backward=False)
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
        of shuffles sums both in every lane, and every lane advances the same state with the
        same arithmetic. What the steps need of the row is read once before them
        (``row_setup``) and passed from step to step. The output y of the next step is the
        modes' free part plus ``gain`` times the force: the modes step beside the next step's force, off its chain. Writes
        ``force = F - force_offset`` (N) and ``accel = d_w''`` (m/s^2); steps without contact
        are those with F = 0.
        """
        block, thread = wp.tid()
        lanes = wp.min(wp.block_dim(), COUPLED_LANES)
        r = block * (wp.block_dim() // lanes) + thread // lanes
        if r >= rows:
            return
        lane = thread % lanes
        row = wp.static(row_setup)(lines, r, contact)
        forces = row_address(force, r)
        accels = row_address(accel, r)
        d_w = d_start
        v = wp.float64(0.0)
        y = wp.float64(0.0)  # the contact point's displacement (m), modal variant
        free = wp.float64(0.0)  # this lane's part of the next y without force
        for s in range(steps):
            F = wp.float64(0.0)
            if wp.static(modal):
                part, row = wp.static(lane_force)(lines, row, first + s, d_w - y, contact, lane, lanes)
                sums = warp_sum_float_pair(wp.vec2d(part, free))
                F = sums[0]
                u = F - F_N
                y = sums[1] + modes.gain * u
                free = modal_step(modes, state, r, u, lane, lanes)
            else:
                part, row = wp.static(lane_force)(lines, row, first + s, d_w, contact, lane, lanes)
                F = warp_sum_float(part)
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

    return coupled_response
