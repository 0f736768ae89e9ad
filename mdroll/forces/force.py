"""Contact force of a batch of rough lines by the registered algorithms (physics.md section 4).

:func:`contact_force` is the public entry point; :func:`force_command` records the force launch
of an algorithm's registry entry (:mod:`mdroll.forces.registry`) on lines prepared by
:func:`~mdroll.forces.prepare.prepare_lines`, which the dynamics reuse.
"""

from __future__ import annotations

import math

import numpy as np

from ..arguments import check_choice, check_params, check_tree_options
from ..checks import check_positive, check_real
from ..devices import device_of, resolve_device, to_warp, warp
from ..errors import ParameterError
from ..params import Params
from .algorithm import LIFTS
from .indenter import lift_table
from .prepare import prepare_lines
from .prepared import DEFAULT_BAND_LIMIT, DEFAULT_LEAF_SIZE, PreparedLines
from .registry import DEFAULT_ALGORITHMS, algorithm_entry
from .steps import BOUNDARIES


def launch_force(prepared: PreparedLines, params: Params, algorithm: str, d: float, device: str, out=None,
                 offset: float = 0.0):
    """The (R, steps) array of ``F - offset`` (N, Warp float64 on ``device``): the force at
    constant indentation d (m), less ``offset`` (N; the pipeline passes F_N, so the series
    holds the small deviation that the spectra need).

    ``out``: a preallocated (R, steps) float64 array to write into.
    """
    command, force = force_command(prepared, params, algorithm, d, device, out, offset)
    command.launch()
    return force


def force_command(prepared: PreparedLines, params: Params, algorithm: str, d: float, device: str, out=None,
                  offset: float = 0.0):
    """The force launch of :func:`launch_force`, recorded (a ``wp.Launch``; run it with
    ``.launch()``), and the array it writes: the host work of a launch (the lift table, the
    arguments' packing) is done here once, so that the scaling study can time the kernel alone. The kernel and its arguments come from the algorithm's registry
    entry (``force_launch``). Keep ``prepared`` alive while the command may run: it owns the
    memory behind its prefix-sum rows (``prefix_owner``)."""
    wp = warp()
    entry = algorithm_entry(algorithm)
    force = out if out is not None else wp.empty((prepared.lines.shape[0], prepared.steps), dtype=wp.float64,
                                                 device=device)
    lifts = lift_table(params, d, prepared.h_top, device) if LIFTS in entry.needs else None
    return entry.force_launch(prepared, params, d, offset, force, lifts, device), force


def _check_finite_lines(data) -> None:
    """Refuse lines holding NaN or infinity (or heights so large that their sum overflows): the
    force of such a line is meaningless, and its window of possible contact unbounded."""
    wp = warp()
    flat = (data if data.is_contiguous else data.contiguous()).flatten()
    if not math.isfinite(float(wp.utils.array_sum(flat))):
        raise ParameterError("lines holds heights that are not finite (NaN or infinity): every height must be a finite "
                             "number of metres")


def contact_force(
    lines,
    params: Params,
    algorithm: str = DEFAULT_ALGORITHMS["decoupled"],
    boundary: str = "open",
    d: float | None = None,
    device: str | None = None,
    *,
    leaf_size: int = DEFAULT_LEAF_SIZE,
    band_limit: int = DEFAULT_BAND_LIMIT,
    h_max: float | None = None,
):
    """Contact force F[r, s] (N) of each line r at each wheel step s, at constant indentation d.

    Parameters
    ----------
    lines : (R, n) or (n,) float64 array, metres
        Rough lines on the grid ``x_i = i dx`` with ``n = params.n_points`` (NumPy, Warp or CuPy).
    params : Params
    algorithm : str
        A name in :data:`~mdroll.forces.registry.ALGORITHMS` (the registry's entries
        describe each): ``direct``, the exact spring sum (eq 10-12) over the window of possible
        contact; ``tree``, the bounding-tree algorithm, equal to ``direct`` to rounding;
        ``edge``, the edge-incremental approximation of eq 49; ``sweep`` (the default), running
        totals over the springs in contact, O(n) and equal to ``direct`` to rounding.
    boundary : {"open", "periodic"}
        ``open``: the thesis's line, wheel from near x_w = a to near L - a
        (:func:`~mdroll.forces.steps.step_range`); ``periodic``: the wheel visits every spring, indices wrap.
    d : float, optional
        Indentation (m); default ``params.d0`` (eq 14).
    device : str, optional
        Where to compute; default the device of ``lines``.
    leaf_size : int
        Springs per tree leaf (tree only).
    band_limit : int
        Tree only: in a line whose band of possible contact (root bounds, one side) holds at
        most this many springs the bands are summed directly, in wider ones by a traversal
        shared by 8 steps, O(log n) a step (a tuning knob; the result is the same to rounding).
    h_max : float, optional
        Height bound (m) that places the open-boundary wheel (default: max of ``lines``).

    Returns
    -------
    force : (R, S) float64, newtons
        NumPy for a NumPy input on the CPU, else a Warp array on the device. The wheel of step s
        is at ``x_w = (first + s) dx`` with ``first`` from :func:`~mdroll.forces.steps.step_range`.
    """
    wp = warp()
    check_params(params)
    algorithm_entry(algorithm)
    check_choice("boundary", boundary, BOUNDARIES)
    leaf_size, band_limit = check_tree_options(leaf_size, band_limit)
    d = check_positive("d", params.d0 if d is None else d, "m, the indentation")
    h_max = None if h_max is None else check_real("h_max", h_max, "m")
    if not hasattr(lines, "dtype"):  # a list of numbers: as NumPy
        try:
            lines = np.asarray(lines, dtype=np.float64)
        except (TypeError, ValueError):
            raise ParameterError(f"lines must be an array of heights (m), got {type(lines).__name__}") from None
    device = resolve_device(device if device is not None else device_of(lines) or "cpu")
    host_input = isinstance(lines, np.ndarray)
    if not isinstance(lines, wp.array) and np.dtype(getattr(lines, "dtype", np.float64)) != np.float64:
        raise ParameterError(f"lines must be float64 (the force path is float64 throughout), got {lines.dtype}")
    one_line = getattr(lines, "ndim", 2) == 1
    data = to_warp(np.ascontiguousarray(np.atleast_2d(lines)) if host_input else lines, device)
    if one_line and not host_input:
        data = (data if data.is_contiguous else data.contiguous()).reshape((1, data.shape[0]))
    if data.ndim != 2 or data.shape[1] != params.n_points:
        raise ParameterError(
            f"lines has shape {tuple(data.shape)}; expected (R, {params.n_points}) or ({params.n_points},) for "
            f"L = {params.L!r} m, dx = {params.dx!r} m"
        )
    if data.dtype != wp.float64:
        raise ParameterError(f"lines must be float64 (the force path is float64 throughout), got {data.dtype}")
    _check_finite_lines(data)
    prepared = prepare_lines(data, params, algorithm, boundary, d, device, leaf_size, h_max, band_limit)
    force = launch_force(prepared, params, algorithm, d, device)
    if host_input and device == "cpu":
        out = force.numpy()
        return out[0] if one_line else out
    return force
