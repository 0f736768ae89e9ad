"""Driving the coupled wheel dynamics (eq 13) over prepared lines: the series of force and acceleration."""

from __future__ import annotations

import numpy as np

from ..devices import warp
from ..kernels.dynamics import COUPLED_LANES, INTEGRATORS, Modes, coupled_track, with_integrator
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


def _modes(form: ModalForm, dt: float, device: str):
    wp = warp()
    phi, gamma = form.discretize(dt)
    modes = Modes()
    modes.phi_re, modes.phi_im, modes.gamma_re, modes.gamma_im = (
        wp.array(np.ascontiguousarray(x), dtype=wp.float64, device=device) for x in (phi.real, phi.imag, gamma.real,
                                                                                        gamma.imag))
    modes.n = form.order
    return modes


def coupled_series(prepared, params: Params, algorithm: str, device: str, d_start: float | None = None,
                   force_offset: float = 0.0, integrator: str = "semi-implicit", compliance=(None, True)):
    """Force (N, less ``force_offset``) and acceleration d'' (m/s^2) series of eq 13 for
    prepared lines (:func:`~mdroll.forces.prepare.prepare_lines`), by the coupled kernel of
    the algorithm's registry entry; the wheel starts at indentation ``d_start`` (m, default d0)
    at rest. Contact is lost where F = 0. An algorithm without a coupled step is refused
    (ParameterError). ``integrator``: one of :data:`~mdroll.kernels.dynamics.INTEGRATORS`
    ("forward-euler", the thesis's scheme, only for the coupling study). ``compliance``:
    :func:`contact_compliance`'s pair; with a state space the contact point moves
    (:func:`~mdroll.kernels.dynamics.coupled_track`, its modes stepped exactly over dt) and
    ``accel`` is the wheel mass's (zero for a modal wheel)."""
    wp = warp()
    kernel, lines = coupled_entry(algorithm).coupled(prepared)
    kernel = with_integrator(kernel, integrator)
    rows = prepared.lines.shape[0]
    force = wp.empty((rows, prepared.steps), dtype=wp.float64, device=device)
    accel = wp.empty_like(force)
    form, rigid_mass = compliance
    extra = []
    if form is not None:
        if integrator != INTEGRATORS[0]:
            raise ParameterError(f"integrator = {integrator!r} is not allowed with a compliant track or wheel: "
                                 f"use {INTEGRATORS[0]!r}")
        kernel = coupled_track(kernel)
        extra = [_modes(form, params.dt, device), wp.zeros((rows, max(form.order, 1)), dtype=wp.vec2d, device=device)]
    wp.launch_tiled(
        kernel,
        dim=[rows],
        block_dim=COUPLED_LANES,
        inputs=[lines, contact_constants(params), prepared.first, prepared.steps,
                params.d0 if d_start is None else d_start, params.F_N, 1.0 / params.m if rigid_mass else 0.0,
                params.dt, force_offset, force, accel, *extra],
        device=device,
    )
    return force, accel

