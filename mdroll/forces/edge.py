"""Host side of the edge-incremental approximation (eq 49, :mod:`mdroll.kernels.edge`): its
geometry, force launch and coupled step, for the registry (:mod:`mdroll.forces.registry`)."""

from __future__ import annotations

import math

from .. import physics
from ..devices import warp
from ..kernels.edge import EdgeGeometry, contact_force_edge, coupled_edge
from ..params import Params


def edge_geometry(params: Params, d: float) -> EdgeGeometry:
    """The :class:`~mdroll.kernels.edge.EdgeGeometry` of eq 49 at indentation d (m), from the
    closed forms of :mod:`mdroll.physics` (the kernel's :func:`~mdroll.kernels.edge.edge_geometry`
    computes the same, in the same order, per step of the coupled dynamics)."""
    a = physics.contact_radius(d, params.R)
    alpha = a / params.dx
    geometry = EdgeGeometry()
    geometry.whole = int(math.floor(alpha))
    geometry.fraction = alpha - geometry.whole
    geometry.hertz = physics.hertz_force(d, params.E_star, params.R)
    geometry.tip = physics.edge_coefficient(params.E_star, params.R, a)
    geometry.dx_E_star = physics.spring_stiffness(params.E_star, params.dx)
    return geometry


def edge_launch(p, params: Params, d: float, offset: float, force, lifts, device):
    """The registry's ``force_launch`` of the edge formula: reads the prefix sums."""
    return warp().launch(contact_force_edge, dim=force.shape, inputs=[p.prefix, p.first, edge_geometry(params, d),
                                                                      offset, force], device=device, record_cmd=True)


def edge_coupled(p):
    """The registry's ``coupled`` of the edge formula: its eq 13 kernel and the prefix sums."""
    return coupled_edge, p.prefix
