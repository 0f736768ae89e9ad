"""Where the wheel rolls on a line (physics.md section 4): the boundaries, the margin the wheel
keeps from an open line's ends, its first spring and its number of steps."""

from __future__ import annotations

import math

from .. import physics
from ..arguments import check_choice
from ..fft import fast_length
from ..errors import ParameterError
from ..params import Params
from .indenter import indenter_curvature, reach

#: The boundaries a line may have (``boundary=`` everywhere): ``open``, the thesis's, where the
#: wheel keeps its window of possible contact on the line, and ``periodic``, where it visits
#: every spring and the line wraps (:func:`step_range`).
BOUNDARIES = ("open", "periodic")


def wheel_margin(params: Params, d: float, h_max: float) -> int:
    """Springs the wheel keeps from either end of an open line (or wraps, periodic).

    The half-width of the window of possible contact, ``max m`` with ``m^2 dx^2 / R <= d + h_max``,
    and at least ``floor(a(d)/dx) + 1`` so that the edge formula's end cells lie on the line.
    """
    curvature = indenter_curvature(params)
    edge_cells = int(math.floor(physics.contact_radius(d, params.R) / params.dx)) + 1
    return max(reach(d + h_max, curvature), edge_cells)


def step_range(params: Params, boundary: str, d: float, h_max: float) -> tuple[int, int]:
    """``(first, steps)``: the wheel's first spring index on the line and the number of steps.

    ``periodic``: the wheel visits every spring, ``x_w = s dx`` for s = 0..n-1 (first = 0).
    ``open`` (the thesis's): the wheel starts at the first spring whose whole window of possible
    contact (``d + h_max``, see :func:`wheel_margin`) lies on the line, so ``x_w`` starts near a,
    and steps one spring at a time while that window stays on the line, for the largest number
    of steps of the form ``2^a 3^b 5^c`` (:func:`mdroll.fft.fast_length`): at most about 1 %
    fewer at 10^6 steps, so that the series' FFTs run at full speed (docs/performance.md,
    "FFT lengths").

    ``d``: the wheel's indentation (m); ``h_max``: the highest roughness on the lines (m).
    Returns ``first`` (a spring index; the wheel's position is ``first dx``, m) and ``steps`` (one
    spring, ``dt = dx / v0`` s, each).
    """
    check_choice("boundary", boundary, BOUNDARIES)
    n = params.n_points
    if boundary == "periodic":
        return 0, n
    margin = wheel_margin(params, d, h_max)
    steps = n - 2 * margin
    if steps < 1:
        raise ParameterError(
            f"L = {params.L!r} m is too short for the open boundary at d = {d:.4g} m, max h = {h_max:.4g} m: "
            f"the window of possible contact spans {2 * margin + 1} springs of the {n} on the line"
        )
    return margin, fast_length(steps)
