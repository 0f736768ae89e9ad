"""Coupled wheel dynamics with the semi-implicit (symplectic) Euler step (physics.md section 5, eq 13).

Time is sequential per realization; one block per realization shares each step's spring sum.
The decoupled response (section 5.1) is linear and needs no time loop: kernels/moments.py.
Semi-implicit Euler: ``v += dt a(y)`` first, then ``y += dt v`` with the new v; plain forward
Euler grows the oscillation's amplitude by exp(N (omega_0 dt)^2 / 2) over N steps (docs/physics.md
section 5: ~35 % in amplitude, ~83 % in energy over ~10^6 steps at the defaults). Forward Euler
(``y += dt v`` with the old v, then ``v += dt a``) is the thesis's scheme ("Euler", section 3.4):
it is kept, as a compile-time variant of the same kernel (:func:`with_integrator`), only to test
whether it explains the thesis's Figure 11 (mdroll study coupling); every amplitude grows by
``sqrt(1 + (omega dt)^2)`` a step under it.

:func:`coupled_dynamics` makes the kernel of one force algorithm from its lane force (its
``wp.func``), compiled apart (``wp.static``): each algorithm's kernel module declares its own.
"""

import warp as wp

from .common import Contact

#: Threads sharing one realization in the coupled dynamics on CUDA: one warp, so the per-step
#: block reduction needs no cross-warp synchronization. Warp runs tiles with one thread on the CPU.
COUPLED_LANES = 32

#: The time steps of eq 13: the semi-implicit (symplectic) Euler step, and forward Euler, the
#: thesis's scheme, for the coupling study only (module docstring).
INTEGRATORS = ("semi-implicit", "forward-euler")

# (lines_type, lane_force) of each semi-implicit kernel, and every kernel made, by its arguments
_MADE_FROM: dict = {}
_KERNELS: dict = {}


@wp.struct
class Modes:
    """The zero-order-hold step of a modal state space (:class:`mdroll.statespace.ModalForm`):
    per mode k, ``q_k <- phi_k q_k + gamma_k u`` (complex) and the output ``y = 2 Re sum_k q_k``."""

    phi_re: wp.array(dtype=wp.float64)
    phi_im: wp.array(dtype=wp.float64)
    gamma_re: wp.array(dtype=wp.float64)
    gamma_im: wp.array(dtype=wp.float64)
    n: int


@wp.func
def modal_step(modes: Modes, state: wp.array2d(dtype=wp.vec2d), r: int, u: wp.float64, lane: int, lanes: int):
    """Steps the modes ``lane, lane + lanes, ...`` of realization r (their complex states
    ``state[r, k]``) over one time step under the force u (N), held over the step; returns
    their part of the new output y (m): the parts of all lanes sum to y."""
    y = wp.float64(0.0)
    for k in range(lane, modes.n, lanes):
        q = state[r, k]
        re = modes.phi_re[k] * q[0] - modes.phi_im[k] * q[1] + modes.gamma_re[k] * u
        im = modes.phi_re[k] * q[1] + modes.phi_im[k] * q[0] + modes.gamma_im[k] * u
        state[r, k] = wp.vec2d(re, im)
        y += wp.float64(2.0) * re
    return y


def coupled_track(kernel: wp.Kernel) -> wp.Kernel:
    """The variant of a kernel of :func:`coupled_dynamics` whose contact point moves: the
    indentation is the wheel mass's minus the output of a modal state space (the rail's and a
    modal wheel's receptances) driven by F - F_N (semi-implicit Euler for the mass)."""
    lines_type, lane_force = _MADE_FROM[kernel]
    key = (lines_type, lane_force, "track")
    made = _KERNELS.get(key)
    if made is None:
        made = _KERNELS[key] = _track_kernel(lines_type, lane_force)
        _MADE_FROM[made] = (lines_type, lane_force)
    return made


def coupled_dynamics(lines_type, lane_force, forward_euler: bool = False) -> wp.Kernel:
    """The eq 13 kernel of the algorithm whose share of a step's force is ``lane_force``.

    ``lane_force(lines: lines_type, r: int, c: int, d: wp.float64, contact: Contact, lane: int,
    lanes: int) -> wp.float64`` returns the part (N) of F(x_w, d) that ``lane`` of ``lanes``
    computes with the wheel at spring c of row r, indentation d (m); the parts of all lanes sum
    to F. ``lines_type``: what the algorithm reads of the lines (a ``wp.struct`` or an array).
    ``forward_euler``: the thesis's forward Euler step instead of the semi-implicit one, chosen
    at compile time (``wp.static``). One kernel per set of arguments, made once.
    """
    made = _KERNELS.get((lines_type, lane_force, forward_euler))
    if made is None:
        made = _KERNELS[(lines_type, lane_force, forward_euler)] = _coupled_kernel(lines_type, lane_force, forward_euler)
        _MADE_FROM[made] = (lines_type, lane_force)
    return made


def with_integrator(kernel: wp.Kernel, integrator: str) -> wp.Kernel:
    """The variant of a kernel of :func:`coupled_dynamics` that steps eq 13 by ``integrator``
    (one of :data:`INTEGRATORS`)."""
    return coupled_dynamics(*_MADE_FROM[kernel], forward_euler=integrator == "forward-euler")


def _coupled_kernel(lines_type, lane_force, forward_euler: bool) -> wp.Kernel:

    @wp.kernel(module="unique")
    def coupled_response(
        lines: lines_type,
        contact: Contact,
        first: int,
        steps: int,
        d_start: wp.float64,
        F_N: wp.float64,
        inv_mass: wp.float64,
        dt: wp.float64,
        force_offset: wp.float64,
        force: wp.array2d(dtype=wp.float64),
        accel: wp.array2d(dtype=wp.float64),
    ):
        """Eq 13: ``m d'' = F_N - F(x_w(t), d(t))``, d(0) = d_start (d0 in the thesis), d'(0) = 0,
        the wheel one spring per step from spring ``first``; semi-implicit Euler steps (forward
        Euler in the ``forward_euler`` variant).

        Launched tiled, one block per realization. Time is sequential, so the block shares each
        step's force instead: every lane computes its part (``lane_force``), a block-wide sum
        combines them, and every lane advances the same (d, d') with the same arithmetic.
        Writes ``force = F - force_offset`` (N) and ``accel = d''`` (m/s^2); steps without
        contact are those with F = 0.
        """
        r, lane = wp.tid()
        lanes = wp.block_dim()
        d = d_start
        v = wp.float64(0.0)
        for s in range(steps):
            part = wp.static(lane_force)(lines, r, first + s, d, contact, lane, lanes)
            F = wp.tile_sum(wp.tile(part))[0]
            a = (F_N - F) * inv_mass
            if lane == 0:
                force[r, s] = F - force_offset
                accel[r, s] = a
            if wp.static(forward_euler):
                d += dt * v  # the old velocity (the thesis's scheme)
                v += dt * a
            else:
                v += dt * a
                d += dt * v

    return coupled_response


def _track_kernel(lines_type, lane_force) -> wp.Kernel:

    @wp.kernel(module="unique")
    def coupled_track_response(
        lines: lines_type,
        contact: Contact,
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
        """Eq 13 with a compliant contact point: the indentation is ``d = d_w - y``, d_w the
        wheel mass's (``m d_w'' = F_N - F``, semi-implicit Euler; ``inv_mass`` 0 holds it at
        d_start) and y the modal state space's output (:func:`modal_step`) driven by F - F_N,
        the force of each step held over it. Everything starts at rest at d_start, states zero
        (``state``). One block per realization as :func:`coupled_dynamics`: the lanes share the
        force and the modes. Writes ``force = F - force_offset`` (N), ``accel = d_w''`` (m/s^2)."""
        r, lane = wp.tid()
        lanes = wp.block_dim()
        d_w = d_start
        v = wp.float64(0.0)
        y = wp.float64(0.0)
        for s in range(steps):
            part = wp.static(lane_force)(lines, r, first + s, d_w - y, contact, lane, lanes)
            F = wp.tile_sum(wp.tile(part))[0]
            a = (F_N - F) * inv_mass
            if lane == 0:
                force[r, s] = F - force_offset
                accel[r, s] = a
            v += dt * a
            d_w += dt * v
            y = wp.tile_sum(wp.tile(modal_step(modes, state, r, F - F_N, lane, lanes)))[0]

    return coupled_track_response
