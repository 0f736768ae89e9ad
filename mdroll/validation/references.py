"""Reference solutions in array code: independent NumPy/CuPy versions of what the kernels
compute, for the checks and tests to compare against (kept apart from the solvers, as
ContactMechanics keeps its reference solutions).

Lines are read as periodic rows (R, n) or one row (n,) of heights h_i (m) on ``x_i = i dx``,
NumPy or CuPy; the wheel sits on every spring, ``x_w = s dx``, s = 0..n-1, and h between springs
is the linear interpolant. The closed forms come from :mod:`mdroll.physics`.
"""

from __future__ import annotations

import math

from .. import physics
from ..devices import array_module
from ..params import Params


def heights_at(lines, offset: float, dx: float):
    """h at ``x_s + offset`` for every spring s of each periodic line, by linear interpolation
    between springs (indices wrap); returns the shifted rows (m) in the array module of ``lines``.
    ``offset`` and ``dx`` in m."""
    xp = array_module(lines)
    whole = math.floor(offset / dx)
    frac = offset / dx - whole
    here = xp.roll(lines, -whole, axis=-1)
    return here + frac * (xp.roll(here, -1, axis=-1) - here)


def edge_quadratic_force(params: Params, lines, d: float | None = None):
    """Reference of the quadratic edge force of eq 48, ``c (h(x_w + a)^2 + h(x_w - a)^2)`` (N), with
    ``c = E* R / (4 a)`` (:func:`mdroll.physics.edge_coefficient`) and ``a = sqrt(d R)``, d = d0
    (eq 14-15) unless given (m). Below q_min this is the whole force fluctuation up to constants
    (physics.md section 7)."""
    a = float(physics.contact_radius(params.d0 if d is None else d, params.R))
    right = heights_at(lines, a, params.dx)
    left = heights_at(lines, -a, params.dx)
    return float(physics.edge_coefficient(params.E_star, params.R, a)) * (right * right + left * left)


def edge_force(params: Params, lines, d: float | None = None):
    """Reference of the edge-incremental force of eq 49 (N), independent of the edge kernel:

        F = F_Hertz(d) + E* integral_{x_w-a}^{x_w+a} h dx + E* R/(4a) (h(x_w+a)^2 + h(x_w-a)^2)

    ``F_Hertz(d)`` from :func:`mdroll.physics.hertz_force`; the integral is exact over the linear
    interpolant of h (the trapezoid rule on whole cells and the two fractional end cells).
    Same inputs and wheel positions as :func:`edge_quadratic_force`.
    """
    xp = array_module(lines)
    d = params.d0 if d is None else d
    a = float(physics.contact_radius(d, params.R))
    dx = params.dx
    whole = math.floor(a / dx)
    # trapezoid rule over springs s - whole .. s + whole from a running sum of the wrapped line
    wrapped = xp.concatenate([lines[..., -whole:], lines, lines[..., : whole + 1]], axis=-1)
    running = xp.cumsum(wrapped, axis=-1)
    n = lines.shape[-1]
    window_sum = running[..., 2 * whole: 2 * whole + n] - xp.concatenate(
        [xp.zeros_like(running[..., :1]), running[..., : n - 1]], axis=-1)
    right_0, left_0 = xp.roll(lines, -whole, axis=-1), xp.roll(lines, whole, axis=-1)
    middle = window_sum - 0.5 * (right_0 + left_0)
    right_1 = heights_at(lines, a, dx)
    left_1 = heights_at(lines, -a, dx)
    partial = a / dx - whole
    ends = 0.5 * partial * ((right_0 + right_1) + (left_0 + left_1))
    integral = dx * (middle + ends)
    # plain Python floats as scalars, so that CuPy rows stay CuPy arrays without relying on NumPy-scalar dispatch
    hertz = float(physics.hertz_force(d, params.E_star, params.R))
    coefficient = float(physics.edge_coefficient(params.E_star, params.R, a))
    return hertz + params.E_star * integral + coefficient * (right_1**2 + left_1**2)
