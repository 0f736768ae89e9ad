"""Normal contact of a rigid indenter on a rough elastic half-space: the constrained conjugate
gradient method of Polonsky & Keer (Wear 231, 206, 1999), batched, on NumPy or CuPy arrays.

Geometry and signs. The grid is n x n cells of side dx, axis 0 along the track, cell centres at
``x_i = (i - (n - 1) / 2) dx`` (and likewise y_j), so the indenter's lowest point lies above the
grid's centre. ``heights`` h_ij (m) is the rough surface of the elastic body, positive up, towards
the indenter. The indenter, a paraboloid of radii R_x along the track and R_y across (a sphere
when equal), is pressed down by the approach d (m) measured from the plane h = 0. The gap after
deformation is

    g_ij = u_ij + x_i^2 / (2 R_x) + y_j^2 / (2 R_y) - h_ij - d,    u = K * p  (halfspace.HalfSpace)

and the contact conditions are ``p >= 0, g >= 0, p g = 0`` on every cell: u (m) is the normal
surface displacement into the body, p (Pa) the contact pressure. The force is
``F = dx^2 sum p`` (N), the contact area ``A = dx^2 #{p > 0}`` (m^2).

Displacement control fixes d; load control fixes F and finds d as the mean of
``u + x^2/(2R_x) + y^2/(2R_y) - h`` over the contact (Polonsky & Keer's gap offset).
"""

from __future__ import annotations

import contextlib
import functools
import math
from dataclasses import dataclass

import numpy as np

from ..errors import DeviceError, ParameterError
from ..physics import hertz_indentation
from .halfspace import HalfSpace

#: Default convergence tolerance: the relative change of the pressure in one iteration,
#: ``sum |p_new - p_old| / sum p_new`` (Polonsky & Keer's criterion).
TOLERANCE = 1e-10
#: Default cap on conjugate-gradient iterations.
MAX_ITERATIONS = 2000


@dataclass
class Contact:
    """One solve: scalars for one surface, arrays of length B for a batch.

    force (N), approach (m), area (m^2), pressure (Pa, like ``heights``: NumPy in, NumPy out; CuPy
    in, CuPy out), iterations (CG iterations), residual (the last relative pressure change),
    converged (residual below the tolerance).
    """

    force: np.ndarray | float
    approach: np.ndarray | float
    area: np.ndarray | float
    pressure: object
    iterations: np.ndarray | int
    residual: np.ndarray | float
    converged: np.ndarray | bool


def array_module(device: str):
    """``(xp, context)`` for a device name: NumPy and a null context on ``"cpu"``; CuPy (imported
    here, lazily) and its device context on ``"cuda"`` / ``"cuda:N"``. Raises
    :class:`mdroll.errors.ParameterError` for another name, :class:`mdroll.errors.DeviceError`
    when CuPy is missing."""
    if device == "cpu":
        return np, contextlib.nullcontext()
    if not isinstance(device, str) or not (device == "cuda" or device.startswith("cuda:")):
        raise ParameterError(f"device must be 'cpu', 'cuda' or 'cuda:N', got {device!r}")
    index = device.partition(":")[2] or "0"
    if not index.isdigit():
        raise ParameterError(f"device must be 'cpu', 'cuda' or 'cuda:N', got {device!r}")
    try:
        import cupy
    except ImportError as exc:
        raise DeviceError(f"device {device!r} needs CuPy for cuFFT: install it with pip install -e '.[cuda]'") from exc
    return cupy, cupy.cuda.Device(int(index))


def indenter_gap(n, dx, radius, radius_y, xp=np):
    """The indenter's height above its lowest point on the cell centres,
    ``x_i^2 / (2 R_x) + y_j^2 / (2 R_y)`` (m), ``x_i = (i - (n - 1) / 2) dx``: the paraboloid
    of the sphere (R_y = R_x) or of the ellipsoid. Returns (n, n) in ``xp``."""
    x = (np.arange(n) - 0.5 * (n - 1)) * dx
    return xp.asarray(x[:, None] ** 2 / (2.0 * radius) + x[None, :] ** 2 / (2.0 * radius_y))


@functools.lru_cache(maxsize=8)
def device_gap(device, n, dx, radius, radius_y):
    """:func:`indenter_gap` on ``device`` (NumPy or CuPy), kept for the next solve of that geometry
    (read only)."""
    xp, context = array_module(device)
    with context:
        return indenter_gap(n, dx, radius, radius_y, xp)


def _positive(name, value):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(value) or value <= 0:
        raise ParameterError(f"{name} must be a positive finite number (SI units), got {value!r}")
    return float(value)


def _control(name, value, batch, positive):
    """The approach or the load as a float64 vector of length ``batch`` (a scalar is repeated)."""
    array = np.asarray(value, dtype=np.float64) if not isinstance(value, bool) else np.asarray([np.nan])
    if array.ndim > 1 or (array.ndim == 1 and array.size != batch) or not np.all(np.isfinite(array)) \
            or (positive and np.any(array <= 0)):
        what = "positive finite" if positive else "finite"
        raise ParameterError(f"{name} must be a {what} number or one per surface ({batch}), got {value!r}")
    return np.broadcast_to(array, (batch,)).copy()


def check_problem(heights, dx, radius, E_star, approach, load, radius_y):
    """Validate the arguments of :func:`solve`; return ``(batched, n, dx, R_x, R_y, E*, control,
    load_control)``. One-line :class:`ParameterError` messages."""
    if (approach is None) == (load is None):
        raise ParameterError("give exactly one of approach (m, displacement control) and load (N, load control)")
    shape = tuple(getattr(heights, "shape", ()))
    if len(shape) not in (2, 3) or shape[-1] != shape[-2] or shape[-1] < 2:
        raise ParameterError(f"heights must be a square grid (n, n) or a stack (B, n, n) with n >= 2, got shape {shape}")
    batch = shape[0] if len(shape) == 3 else 1
    dx, radius, E_star = _positive("dx", dx), _positive("radius", radius), _positive("E_star", E_star)
    radius_y = radius if radius_y is None else _positive("radius_y", radius_y)
    control = _control("load" if approach is None else "approach", approach if load is None else load,
                       batch, positive=load is not None)
    return len(shape) == 3, shape[-1], dx, radius, radius_y, E_star, control, load is not None


def check_stopping(tol, max_iter):
    """The tolerance (positive) and the iteration cap (a positive int), or a ParameterError."""
    if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
        raise ParameterError(f"max_iter must be a positive integer, got {max_iter!r}")
    return _positive("tol", tol), int(max_iter)


def _sum(a):
    return a.sum(axis=(-2, -1))


def _column(a):
    return a[:, None, None]


def initial_pressure(op, separation, control, load_control, radius_mean):
    """A first pressure: the indenter's rigid overlap ``w = max(d - s, 0)`` (s the separation
    before deformation) scaled to the load (load control, d from Hertz's eq 14 for the load
    with the radius sqrt(R_x R_y) above the first point to touch), or by the factor
    ``k = <w, K w> / <K w, K w>`` that best cancels the overlap (displacement control)."""
    xp, dx = op.xp, op.dx
    if load_control:
        lowest = separation.min(axis=(-2, -1))
        reach = xp.asarray(hertz_indentation(control, op.E_star, radius_mean)) + lowest
        overlap = xp.maximum(_column(reach) - separation, 0.0)
        return overlap * _column(xp.asarray(control) / (dx * dx * _sum(overlap)))
    overlap = xp.maximum(_column(xp.asarray(control)) - separation, 0.0)
    response = op.displacement(overlap)
    norm = _sum(response * response)
    scale = xp.where(norm > 0, _sum(overlap * response) / xp.where(norm > 0, norm, 1.0), 0.0)
    return overlap * _column(scale)


def constrained_cg(op, separation, control, load_control, pressure, tol, max_iter):
    """Polonsky & Keer's iteration on a batch (B, n, n), every member until its own convergence.

    With the contact set I = {p > 0} and the gap g = u + s - d (s the separation before
    deformation; d fixed, or the mean of u + s over I under load control):

        G = sum_I g^2,  t = g + delta (G / G_old) t on I (0 elsewhere),  r = K t
        (load control: r -= mean_I r),  tau = sum_I g t / sum_I r t,  p <- max(p - tau t, 0),
        p <- p - tau g where p = 0 and g < 0 (then delta = 0, else 1),
        load control: p <- p F / (dx^2 sum p)

    until ``sum |p_new - p_old| / sum p_new < tol``. Returns ``(p, d, iterations, residual)``.
    """
    xp = op.xp
    batch = separation.shape[0]
    target = xp.asarray(control)
    t = xp.zeros_like(pressure)
    g_old = xp.ones(batch)
    delta = xp.zeros(batch)
    active = xp.ones(batch, dtype=bool)
    iterations = xp.zeros(batch, dtype=np.int64)
    residual = xp.full(batch, np.inf)
    approach = target
    for _ in range(max_iter):
        gap = op.displacement(pressure) + separation
        contact = pressure > 0
        count = xp.maximum(_sum(contact), 1)
        if load_control:
            approach = xp.where(active, _sum(gap * contact) / count, approach)
        gap = gap - _column(approach)
        big_g = _sum(contact * gap * gap)
        ratio = xp.where(g_old > 0, delta * big_g / xp.where(g_old > 0, g_old, 1.0), 0.0)
        t = contact * (gap + _column(ratio) * t)
        r = op.displacement(t)
        if load_control:
            r = r - _column(_sum(contact * r) / count)
        curvature = _sum(contact * r * t)
        tau = xp.where(curvature > 0, _sum(contact * gap * t) / xp.where(curvature > 0, curvature, 1.0), 0.0)
        new = xp.maximum(pressure - _column(tau) * t, 0.0)
        overlap = (new == 0) & (gap < 0)
        new = xp.where(overlap, new - _column(tau) * gap, new)
        delta = xp.where(overlap.any(axis=(-2, -1)), 0.0, 1.0)
        total = _sum(new)
        if load_control:
            new = new * _column(xp.where(total > 0, target / (op.dx * op.dx * xp.where(total > 0, total, 1.0)), 0.0))
            total = _sum(new)
        change = xp.where(total > 0, _sum(xp.abs(new - pressure)) / xp.where(total > 0, total, 1.0), 0.0)
        pressure = xp.where(_column(active), new, pressure)
        residual = xp.where(active, change, residual)
        iterations = iterations + active
        g_old = big_g
        active = active & (change >= tol)
        if not bool(active.any()):
            break
    return pressure, approach, iterations, residual


def iteration(op, batch, load_control):
    """The constrained conjugate gradients for ``op``'s arrays, as a call ``(separation, control,
    pressure, tol, max_iter) -> (p, d, iterations, residual)``: :func:`constrained_cg` on NumPy; on
    CuPy the same iteration fused into a few kernels replayed as a CUDA graph
    (:class:`mdroll.bem.fused.FusedCG`), whose buffers serve every later call of the batch."""
    if op.xp is np:
        return lambda separation, control, pressure, tol, max_iter: constrained_cg(
            op, separation, control, load_control, pressure, tol, max_iter)
    from .fused import FusedCG

    return FusedCG(op, batch, load_control)


@functools.lru_cache(maxsize=4)
def workspace(device, n, dx, E_star, batch, load_control):
    """The half-space operator and the solver (:func:`iteration`) of one problem size, kept for the
    next :func:`solve` of that size: the Love coefficients' spectrum and, on CUDA, the solver's
    buffers, cuFFT plans and CUDA graph are built once (the last four sizes stay allocated)."""
    xp, _ = array_module(device)
    op = HalfSpace(n, dx, E_star, xp=xp)
    return op, iteration(op, batch, load_control)


def solve(heights, dx, radius, *, E_star, approach=None, load=None, radius_y=None, device="cpu",
          tol=TOLERANCE, max_iter=MAX_ITERATIONS, initial=None):
    """Normal contact of a rigid sphere (or ellipsoid) on a rough elastic half-space, free boundary.

    Parameters
    ----------
    heights : (n, n) or (B, n, n) array, m
        The elastic body's rough surface, positive up (towards the indenter), on square cells of
        side ``dx``; axis 0 along the track. The indenter's lowest point lies above the grid's
        centre (module docstring). NumPy, or CuPy on CUDA. A stack is solved at once.
    dx : float
        Cell side (m).
    radius : float
        Indenter radius along the track R_x (m); across it too unless ``radius_y`` is given.
    E_star : float
        Composite modulus E* (Pa; eq 1-2 for two bodies of one steel).
    approach, load : float or (B,) array
        Exactly one: the approach d (m; displacement control) or the normal force F (N; load control).
    radius_y : float, optional
        Indenter radius across the track R_y (m): an ellipsoid (e.g. the rail's crown radius).
    device : str
        ``"cpu"`` (NumPy) or ``"cuda"`` / ``"cuda:N"`` (CuPy, cuFFT; imported only then).
    tol : float
        Stop when the relative pressure change of one iteration is below it.
    max_iter : int
        Cap on iterations (a member that hits it returns ``converged = False``).
    initial : array like ``heights``, optional
        Pressure (Pa) to start from (a warm start), instead of the rigid overlap.

    Returns
    -------
    Contact
        force (N), approach (m), area (m^2), pressure (Pa), iterations, residual, converged.
    """
    batched, n, dx, radius, radius_y, E_star, control, load_control = check_problem(
        heights, dx, radius, E_star, approach, load, radius_y)
    tol, max_iter = check_stopping(tol, max_iter)
    xp, context = array_module(device)
    with context:
        surface = xp.asarray(heights, dtype=xp.float64).reshape(-1, n, n)
        op, solver = workspace(device, n, dx, E_star, surface.shape[0], load_control)
        separation = device_gap(device, n, dx, radius, radius_y) - surface
        if initial is None:
            start = initial_pressure(op, separation, control, load_control, math.sqrt(radius * radius_y))
        else:
            start = xp.asarray(initial, dtype=xp.float64).reshape(-1, n, n)
        p, d, iterations, residual = solver(separation, control, start, tol, max_iter)
        result = summarize(p, d, iterations, residual, tol, dx)
    pressure = result.pressure if type(heights).__module__.startswith("cupy") else to_host(result.pressure)
    return unbatch(result, pressure, batched)


def to_host(array):
    """A NumPy copy of a CuPy array (NumPy arrays and scalars as they are)."""
    return array.get() if hasattr(array, "get") else np.asarray(array)


def summarize(pressure, approach, iterations, residual, tol, dx) -> Contact:
    """A batched :class:`Contact` from the solver's state (scalars on the host, pressure as is)."""
    force = to_host(_sum(pressure)) * dx * dx
    area = to_host(_sum(pressure > 0)) * dx * dx
    residual = to_host(residual)
    return Contact(force=force, approach=to_host(approach) * np.ones_like(force), area=area, pressure=pressure,
                   iterations=to_host(iterations), residual=residual, converged=residual < tol)


def unbatch(result: Contact, pressure, batched: bool) -> Contact:
    """``result`` with ``pressure``; its batch of one taken apart into scalars unless ``batched``."""
    if batched:
        return Contact(**{**result.__dict__, "pressure": pressure})
    return Contact(force=float(result.force[0]), approach=float(result.approach[0]), area=float(result.area[0]),
                   pressure=pressure[0], iterations=int(result.iterations[0]), residual=float(result.residual[0]),
                   converged=bool(result.converged[0]))
