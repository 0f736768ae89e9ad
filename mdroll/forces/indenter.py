"""The MDR indenter on the spring grid (physics.md sections 2 and 4): its curvature, the reach of
a spring, the kernels' contact constants and the lift table the blocked kernels read."""

from __future__ import annotations

import math

from .. import physics
from ..devices import warp
from ..kernels.common import BLOCK, Contact, indenter_lifts
from ..errors import ParameterError
from ..params import MAX_POINTS, Params


def indenter_curvature(params: Params) -> float:
    """``g(dx) = dx^2 / R`` (m, eq 7): the MDR indenter lowers the spring m places from the
    wheel by ``curvature m^2``."""
    return physics.indenter_profile(params.dx, params.R)


def contact_constants(params: Params) -> Contact:
    """The :class:`~mdroll.kernels.common.Contact` of ``params``: dx, R, E*, the indenter's
    curvature (:func:`indenter_curvature`) and the spring stiffness ``E* dx`` (N/m, eq 11-12)."""
    contact = Contact()
    contact.dx, contact.R, contact.E_star = params.dx, params.R, params.E_star
    contact.curvature = indenter_curvature(params)
    contact.k_spring = params.k_spring
    return contact


def reach(level: float, curvature: float) -> int:
    """Largest m >= 0 with ``curvature m^2 <= level`` (-1 if level < 0); the host twin of
    :func:`mdroll.kernels.common.reach_inclusive`. A level whose window would span more than
    ``MAX_POINTS`` springs (no line holds more), or is not finite, is refused: the loops below
    then stay a few rounding steps long."""
    if level < 0:
        return -1
    root = math.sqrt(level / curvature) if math.isfinite(level) else math.inf
    if not root <= MAX_POINTS:
        raise ParameterError(
            f"indentation plus height {level:.4g} m gives a window of possible contact of {root:.3g} springs a side, "
            f"more than the {MAX_POINTS} any line holds: the heights (h0, or the lines given) are absurd"
        )
    m = int(math.floor(root))
    while m > 0 and curvature * m * m > level:
        m -= 1
    while curvature * (m + 1) * (m + 1) <= level:
        m += 1
    return m


def reach_strict(level: float, curvature: float) -> int:
    """Largest m >= 0 with ``curvature m^2 < level`` (-1 if level <= 0): the host twin of
    :func:`mdroll.kernels.common.reach_strict`, the reach M of a spring with ``h + d = level``."""
    if level <= 0:
        return -1
    m = int(math.floor(math.sqrt(level / curvature)))
    while m >= 0 and curvature * m * m >= level:
        m -= 1
    while curvature * (m + 1) * (m + 1) < level:
        m += 1
    return m


def lift_table(params: Params, d: float, h_top: float, device: str):
    """The indenter profile ``d - curvature m^2`` (m) at offsets ``|m| <= window + BLOCK`` (the window
    of possible contact for heights up to ``h_top``, plus the blocked sums' padding), as a Warp
    array on ``device``, and the index of m = 0: the table the register-blocked kernels read
    instead of recomputing it. Made by a kernel where it is read: an upload from pageable host
    memory would wait for the device's queue to drain."""
    wp = warp()
    curvature = indenter_curvature(params)
    reach_out = max(reach(d + h_top, curvature), 0) + BLOCK
    lifts = wp.empty(2 * reach_out + 1, dtype=wp.float64, device=device)
    wp.launch(indenter_lifts, dim=lifts.shape, inputs=[d, curvature, reach_out, lifts], device=device)
    return lifts, reach_out
