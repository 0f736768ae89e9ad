"""Driving the coupled wheel dynamics (eq 13) over prepared lines: the series of force and acceleration."""

from __future__ import annotations

from ..devices import warp
from ..kernels.dynamics import COUPLED_LANES, with_integrator
from ..params import Params
from ..forces.indenter import contact_constants
from ..forces.registry import coupled_entry


def coupled_series(prepared, params: Params, algorithm: str, device: str, d_start: float | None = None,
                   force_offset: float = 0.0, integrator: str = "semi-implicit"):
    """Force (N, less ``force_offset``) and acceleration d'' (m/s^2) series of eq 13 for
    prepared lines (:func:`~mdroll.forces.prepare.prepare_lines`), by the coupled kernel of
    the algorithm's registry entry; the wheel starts at indentation ``d_start`` (m, default d0)
    at rest. Contact is lost where F = 0. An algorithm without a coupled step is refused
    (ParameterError). ``integrator``: one of :data:`~mdroll.kernels.dynamics.INTEGRATORS`
    ("forward-euler", the thesis's scheme, only for the coupling study)."""
    wp = warp()
    kernel, lines = coupled_entry(algorithm).coupled(prepared)
    kernel = with_integrator(kernel, integrator)
    rows = prepared.lines.shape[0]
    force = wp.empty((rows, prepared.steps), dtype=wp.float64, device=device)
    accel = wp.empty_like(force)
    wp.launch_tiled(
        kernel,
        dim=[rows],
        block_dim=COUPLED_LANES,
        inputs=[lines, contact_constants(params), prepared.first, prepared.steps,
                params.d0 if d_start is None else d_start, params.F_N, 1.0 / params.m, params.dt, force_offset, force,
                accel],
        device=device,
    )
    return force, accel
