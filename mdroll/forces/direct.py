"""Host side of the direct spring sum (:mod:`mdroll.kernels.direct`): its force launch and its
coupled step, for the registry (:mod:`mdroll.forces.registry`)."""

from __future__ import annotations

from ..kernels.direct import DirectLines, contact_force_direct, coupled_direct
from ..params import Params
from .blocked import blocked_launch
from .indenter import indenter_curvature


def direct_launch(p, params: Params, d: float, offset: float, force, lifts, device):
    """The registry's ``force_launch`` of the direct sum: reads the row bounds and the lift table."""
    table, origin = lifts
    inputs = [p.lines, p.bounds, table, origin, p.n_work, p.first, p.steps, d, indenter_curvature(params),
              params.k_spring, offset, force]
    return blocked_launch(contact_force_direct, inputs, force, device)


def direct_coupled(p):
    """The registry's ``coupled`` of the direct sum: its eq 13 kernel and :class:`DirectLines`."""
    lines = DirectLines()
    lines.h, lines.bounds, lines.n = p.lines, p.bounds, p.n_work
    return coupled_direct, lines
