"""Driving the coupled wheel dynamics (eq 13) over prepared lines: the series of force and acceleration."""

from __future__ import annotations

import numpy as np

from ..devices import is_cuda, warp
from ..kernels.dynamics import (COUPLED_HELPERS, COUPLED_LANES, COUPLED_WARPS, HELPED_REGISTERS, INTEGRATORS,
                                coupled_track, with_helpers, with_integrator)
from ..kernels.modal import LOOKAHEAD, ModalTaps, Modes
from ..params import ParameterError, Params
from ..forces.indenter import contact_constants
from ..forces.registry import coupled_entry
from ..statespace import ModalForm
from ..track import Track
from ..track.fit import rail_modal_form
from ..wheel import Wheel


def contact_compliance(track: Track | None, wheel: Wheel | None, position: str = "sleeper"):
    """The contact point's motion for the coupled dynamics: ``(form, rigid_mass)``, the modal
    state space of the receptances the contact force drives (the rail's fit where the wheel
    stands, plus a modal wheel's modes) and whether the wheel is the rigid mass of eq 13.
    ``form`` is None for the rigid track under the rigid wheel: today's eq 13 exactly."""
    track = track or Track.preset("rigid")
    wheel = wheel or Wheel.preset("rigid")
    form = rail_modal_form(track, position)
    if wheel.kind != "rigid":
        form = wheel.modal_form() + form
    return (None if form.order == 0 and wheel.kind == "rigid" else form), wheel.kind == "rigid"


def _modes(form: ModalForm | None, dt: float, device: str):
    """The kernel's :class:`~mdroll.kernels.modal.Modes` of ``form`` stepped over dt, with the
    look-ahead of :data:`~mdroll.kernels.modal.LOOKAHEAD` steps worked out in float64 (none for
    the rigid contact point)."""
    wp = warp()
    modes = Modes()
    modes.n, modes.taps = 0, ModalTaps()
    if form is not None:
        phi, gamma = form.discretize(dt)
        powers = phi[None, :] ** np.arange(LOOKAHEAD + 1)[:, None]  # phi^0 ... phi^m per mode
        drive = powers[LOOKAHEAD] * gamma
        modes.phi_re, modes.phi_im, modes.input_re, modes.input_im = (
            wp.array(np.ascontiguousarray(x), dtype=wp.float64, device=device) for x in (phi.real, phi.imag,
                                                                                            drive.real, drive.imag))
        modes.n, modes.taps = form.order, ModalTaps(*(2.0 * np.sum(powers[:LOOKAHEAD] * gamma, axis=1).real))
    return modes


def coupled_layout(rows: int, device: str, warps: int | None = None) -> tuple[int, int]:
    """``(blocks, block_dim)`` of a coupled launch of ``rows`` realizations: on CUDA ``warps``
    realizations (warps of :data:`~mdroll.kernels.dynamics.COUPLED_LANES` lanes) a block,
    default :data:`~mdroll.kernels.dynamics.COUPLED_WARPS`; on the CPU, where Warp runs a block
    with one lane, one realization a block."""
    warps = COUPLED_WARPS if warps is None else warps
    if not 1 <= warps <= 32:
        raise ParameterError(f"warps = {warps}: allowed are 1 to 32 realizations a block")
    per_block = warps if is_cuda(device) else 1
    return -(-rows // per_block), COUPLED_LANES * warps


#: 32-bit registers of a multiprocessor: 64 K on every architecture Warp builds for (sm_70 on).
REGISTERS_PER_MULTIPROCESSOR = 65536

#: Waves of a helped coupled launch (:func:`helped_wave`) up to which a launch on CUDA prepares
#: its steps with helper warps, for the rigid contact point and for a modal one (a track or an
#: elastic wheel); beyond, the band is summed directly. A realization's steps are latency-bound,
#: so a helped launch takes about one stepping warp's run a wave begun, while the direct launch
#: hardly grows with its realizations (docs/performance.md, "Coupled batches").
HELPED_WAVES = {False: 3, True: 1}

#: The time of a direct launch of a whole memory batch, in helped waves (the same keys): the cost
#: :func:`plan_batches` weighs a direct batch by (docs/performance.md, "Coupled batches").
DIRECT_WAVE_TIMES = {False: 3.3, True: 2.1}


def helped_wave(device: str) -> int:
    """Realizations a helped coupled launch (:func:`~mdroll.kernels.dynamics.with_helpers`) runs
    at once on the CUDA ``device``: its blocks of one realization (1 + COUPLED_HELPERS warps at
    HELPED_REGISTERS registers a lane) resident together on every multiprocessor."""
    per_multiprocessor = REGISTERS_PER_MULTIPROCESSOR // (HELPED_REGISTERS * COUPLED_LANES * (1 + COUPLED_HELPERS))
    return per_multiprocessor * warp().get_device(device).sm_count


def coupled_helpers(rows: int, device: str, helpers: int | None = None, modal: bool = False) -> int:
    """Helper warps a realization in a coupled launch on CUDA of ``rows`` realizations: by
    default :data:`~mdroll.kernels.dynamics.COUPLED_HELPERS` up to :data:`HELPED_WAVES` waves
    (``modal``: the contact point's), none beyond; 0 to 31."""
    if helpers is not None:
        if not 0 <= helpers <= 31:
            raise ParameterError(f"helpers = {helpers}: allowed are 0 to 31 helper warps a realization")
        return helpers
    if not is_cuda(device):
        return 0
    return COUPLED_HELPERS if rows <= HELPED_WAVES[modal] * helped_wave(device) else 0


def plan_batches(count: int, batch: int, wave: int, helped_waves: int, direct_waves: float) -> list[int]:
    """The batch sizes, in order, of ``count`` realizations of a coupled run whose memory holds
    ``batch``, least in time when a helped launch (of at most ``helped_waves`` waves of ``wave``
    realizations) takes one time unit a wave begun and a direct one (of more than
    ``helped_waves`` waves, at most ``batch``) takes ``direct_waves``: some whole memory batches
    run directly, the rest in helped launches of as many whole waves as fit, the last partial,
    or in one more direct batch where that is cheaper."""
    helped = min(helped_waves, batch // wave) * wave  # the largest helped launch the memory holds
    if helped == 0:
        return _chunks(count, batch)
    direct = batch > helped_waves * wave
    best = (float("inf"), [])
    for full in range(count // batch + 1 if direct else 1):
        rest = count - full * batch
        tail = _chunks(rest, helped)
        cost = full * direct_waves + -(-rest // wave)
        if direct and helped < rest <= batch and (full + 1) * direct_waves < cost:
            cost, tail = (full + 1) * direct_waves, [rest]
        if cost < best[0]:
            best = (cost, [batch] * full + tail)
    return best[1]


def coupled_plan(count: int, batch: int, algorithm: str, modal: bool, device: str) -> list[int]:
    """The batch sizes of a coupled run of ``count`` realizations whose memory holds ``batch``: on
    CUDA, for an algorithm whose steps helpers prepare (``prepares_ahead``),
    :func:`plan_batches` with the device's :func:`helped_wave`, :data:`HELPED_WAVES` and
    :data:`DIRECT_WAVE_TIMES` of the contact point (``modal``), so that a run's realizations split
    over devices go as fast on each as its share allows; elsewhere batches of ``batch``."""
    if not is_cuda(device) or not coupled_entry(algorithm).prepares_ahead:
        return _chunks(count, batch)
    return plan_batches(count, batch, helped_wave(device), HELPED_WAVES[modal], DIRECT_WAVE_TIMES[modal])


def _chunks(count: int, size: int) -> list[int]:
    """``count`` in parts of ``size``, the last the rest."""
    return [size] * (count // size) + ([count % size] if count % size else [])


def coupled_series(prepared, params: Params, algorithm: str, device: str, d_start: float | None = None,
                   force_offset: float = 0.0, integrator: str = "semi-implicit", compliance=(None, True),
                   warps: int | None = None, helpers: int | None = None):
    """Force (N, less ``force_offset``) and acceleration d'' (m/s^2) series of eq 13 for
    prepared lines (:func:`~mdroll.forces.prepare.prepare_lines`), by the coupled kernel of
    the algorithm's registry entry; the wheel starts at indentation ``d_start`` (m, default d0)
    at rest. Contact is lost where F = 0. An algorithm without a coupled step is refused
    (ParameterError). ``integrator``: one of :data:`~mdroll.kernels.dynamics.INTEGRATORS`
    ("forward-euler", the thesis's scheme, only for the coupling study). ``compliance``:
    :func:`contact_compliance`'s pair; with a state space the contact point moves
    (:func:`~mdroll.kernels.dynamics.coupled_track`, its modes stepped exactly over dt) and
    ``accel`` is the wheel mass's (zero for a modal wheel). ``warps``: realizations a block on
    CUDA (:func:`coupled_layout`). ``helpers``: helper warps a realization on CUDA
    (:func:`coupled_helpers`); with any, or on the CPU, an algorithm that can prepares its
    steps ahead (:func:`~mdroll.kernels.dynamics.with_helpers`), one realization a block."""
    wp = warp()
    kernel, lines = coupled_entry(algorithm).coupled(prepared)
    kernel = with_integrator(kernel, integrator)
    rows = prepared.lines.shape[0]
    force = wp.empty((rows, prepared.steps), dtype=wp.float64, device=device)
    accel = wp.empty_like(force)
    form, rigid_mass = compliance
    state = None
    if form is not None:
        if integrator != INTEGRATORS[0]:
            raise ParameterError(f"integrator = {integrator!r} is not allowed with a compliant track or wheel: "
                                 f"use {INTEGRATORS[0]!r}")
        kernel = coupled_track(kernel)
        state = wp.zeros((rows, form.order), dtype=wp.vec2d, device=device)
    blocks, block_dim = coupled_layout(rows, device, warps)
    helpers = coupled_helpers(rows, device, helpers, modal=form is not None)
    helped = with_helpers(kernel)
    if helped is not None and (helpers > 0 or not is_cuda(device)):
        kernel, blocks, block_dim = helped, rows, COUPLED_LANES * (1 + helpers)
    wp.launch_tiled(
        kernel,
        dim=[blocks],
        block_dim=block_dim,
        inputs=[lines, contact_constants(params), rows, prepared.first, prepared.steps,
                params.d0 if d_start is None else d_start, params.F_N, 1.0 / params.m if rigid_mass else 0.0,
                params.dt, force_offset, force, accel, _modes(form, params.dt, device), state],
        device=device,
    )
    return force, accel

