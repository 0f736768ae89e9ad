"""Quasi-static rolling: the indenter moved along the track one cell at a time over a rough
surface larger than the contact window, the contact solved at every position, a batch of
realizations at once, each position warm-started from the last.

Position s (s = 0 .. steps - 1) solves the window of rows ``start + s .. start + s + n - 1`` of the
surface (axis 0 along the track) and its n middle columns, with the indenter's lowest point above
the window's centre: at ``x_s = (start + s + (n - 1) / 2) dx`` along the surface. Between
positions the surface moves one row under the indenter, so the last pressure shifted back by one
row (``p[i] <- p[i + 1]``, the new last row 0) starts the next solve: asperity contacts stay
where they were on the surface. On NumPy the positions are solved one after the other for the
whole batch; on CUDA each member moves on as soon as it converged (:class:`mdroll.bem.fused.FusedRoll`),
with the same solves.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from .halfspace import HalfSpace
from .solver import (MAX_ITERATIONS, TOLERANCE, array_module, check_problem, check_stopping, indenter_gap,
                     initial_pressure, iteration, summarize, to_host)


@dataclass
class Rolling:
    """A rolling run: arrays (B, steps) for B realizations (``(steps,)`` for one surface).

    position (m, ``(steps,)``: the indenter's lowest point along the surface), force (N),
    approach (m), area (m^2), iterations, residual, converged; pressure (Pa) at the last position,
    (B, n, n) or (n, n), on the host.
    """

    position: np.ndarray
    force: np.ndarray
    approach: np.ndarray
    area: np.ndarray
    iterations: np.ndarray
    residual: np.ndarray
    converged: np.ndarray
    pressure: np.ndarray


def shift_back(xp, pressure):
    """``p[..., i, :] <- p[..., i + 1, :]``, the last row 0: the pressure carried with the
    surface when the indenter advances one row."""
    shifted = xp.empty_like(pressure)
    shifted[..., :-1, :] = pressure[..., 1:, :]
    shifted[..., -1, :] = 0.0
    return shifted


def _roll_steps(op, full, gap, start, columns, steps, control, load_control, tol, max_iter, fresh):
    """The positions one after the other (NumPy): each solve started from the last pressure shifted
    back one row. Returns the fields (B, steps) and the last pressure."""
    xp, n = op.xp, op.n
    solver = iteration(op, full.shape[0], load_control)
    pressure, rows = None, []
    for s in range(steps):
        separation = gap - full[:, start + s:start + s + n, columns]
        if pressure is None:
            pressure = fresh(separation)
        else:  # a member that lost contact starts afresh: no pressure, no direction to search
            pressure = shift_back(xp, pressure)
            lost = pressure.sum(axis=(-2, -1)) == 0
            if lost.any():
                pressure = xp.where(lost[:, None, None], fresh(separation), pressure)
        pressure, d, iterations, residual = solver(separation, control, pressure, tol, max_iter)
        rows.append(summarize(pressure, d, iterations, residual, tol, op.dx))
    fields = {name: np.stack([getattr(r, name) for r in rows], axis=-1)
              for name in ("force", "approach", "area", "iterations", "residual", "converged")}
    return fields, to_host(pressure)


def check_rolling(surface, steps, window, start, smallest_window: int) -> tuple[tuple, int]:
    """``(surface's shape, the window's cells n)`` of a rolling run: ``surface`` (Lx, Ly) or
    (B, Lx, Ly); ``steps`` >= 1, ``window`` (default Ly) >= ``smallest_window`` and ``start`` >= 0
    integers with ``n <= Ly`` and ``start + steps - 1 + n <= Lx``; else ParameterError naming them."""
    shape = tuple(getattr(surface, "shape", ()))
    if len(shape) not in (2, 3):
        raise ParameterError(f"surface must be (Lx, Ly) or (B, Lx, Ly), got shape {shape}")
    length, width = shape[-2:]
    n = width if window is None else window
    for name, value, low in (("steps", steps, 1), ("window", n, smallest_window), ("start", start, 0)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
            raise ParameterError(f"{name} must be an integer >= {low}, got {value!r}")
    if n > width or start + steps - 1 + n > length:
        raise ParameterError(f"{steps} positions of a {n}-cell window from row {start} need a surface of at least "
                             f"{start + steps - 1 + n} x {n} cells, got {length} x {width}")
    return shape, n


def roll(surface, dx, radius, *, E_star, steps, approach=None, load=None, window=None, start=0, radius_y=None,
         device="cpu", tol=TOLERANCE, max_iter=MAX_ITERATIONS):
    """Roll the indenter along axis 0 of ``surface`` for ``steps`` positions, one cell apart.

    Parameters
    ----------
    surface : (Lx, Ly) or (B, Lx, Ly) array, m
        Rough surface(s), positive up (:func:`mdroll.bem.solve`'s convention), cells of side dx.
    dx, radius, E_star, approach, load, radius_y, device, tol, max_iter
        As :func:`mdroll.bem.solve`; the approach (m) or load (N) is held at every position
        (a scalar, or one per realization).
    steps : int
        Positions.
    window : int, optional
        Cells n of the square contact window (default Ly); ``start + steps - 1 + n <= Lx``.
    start : int
        Row of the surface where the first window begins.

    Returns
    -------
    Rolling
    """
    shape, n = check_rolling(surface, steps, window, start, smallest_window=2)
    length, width = shape[-2:]
    columns = slice((width - n) // 2, (width - n) // 2 + n)
    batched = len(shape) == 3
    _, n, dx, radius, radius_y, E_star, control, load_control = check_problem(
        np.empty((shape[0] if batched else 1, n, n)), dx, radius, E_star, approach, load, radius_y)
    tol, max_iter = check_stopping(tol, max_iter)
    xp, context = array_module(device)
    with context:
        op = HalfSpace(n, dx, E_star, xp=xp)
        gap = indenter_gap(n, dx, radius, radius_y, xp)
        full = xp.asarray(surface, dtype=xp.float64).reshape(-1, length, width)

        def fresh(separation):
            return initial_pressure(op, separation, control, load_control, math.sqrt(radius * radius_y))

        if xp is np:
            fields, last = _roll_steps(op, full, gap, start, columns, steps, control, load_control, tol, max_iter,
                                       fresh)
        else:
            from .fused import FusedRoll

            first = gap - full[:, start:start + n, columns]
            *values, last = FusedRoll(op, full, gap, start, columns.start, steps, load_control).run(
                first, control, fresh(first), tol, max_iter, fresh)
            fields = dict(zip(("force", "approach", "area", "iterations", "residual"), values))
            fields["converged"] = fields["residual"] < tol
    if not batched:
        fields = {name: value[0] for name, value in fields.items()}
        last = last[0]
    position = (start + np.arange(steps) + 0.5 * (n - 1)) * dx
    return Rolling(position=position, pressure=last, **fields)
