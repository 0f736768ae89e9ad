"""The distributed point-reacting spring (DPRS) model of the wheel/rail contact: Remington & Webb,
"Estimation of wheel/rail interaction forces in the contact area due to roughness", J. Sound
Vib. 193(1), 83-102 (1996), in the 3-D form of Ford & Thompson, "Simplified contact filters in
wheel/rail noise prediction", J. Sound Vib. (2006); docs/mdr-vs-3d.md.

The contact zone is a bed of independent springs of stiffness kappa per unit area (N/m^3). At
the approach delta a spring at (x, y) under the indenter is compressed by

    w(x, y) = delta - z(x, y) + h(x, y),       z = delta (x^2 / a^2 + y^2 / b^2),

h the rough surface (positive up, towards the indenter, as in :func:`mdroll.bem.solve`); a
spring in tension carries nothing, so the force is ``F = kappa integral max(w, 0) dA`` (non-linear
where the contact opens). A bed of independent springs under a sphere of radius R touches on
``a^2 = 2 R delta``, twice Hertz's area at the same approach, so the model halves the radii,
``z = x^2 / R_x + y^2 / R_y``, for the static patch to be Hertz's. Here the bed's paraboloid is
the one whose smooth contact at delta is Hertz's ellipse of semi-axes a (along the track) and b:
for a sphere at Hertz's approach d, ``a^2 = R d`` and z is exactly the halved radius's
``x^2 / R + y^2 / R``; for an ellipsoid, halving both radii would not give Hertz's ellipse, whose
axis ratio is not ``sqrt(R_y / R_x)``.

Static load. On a smooth surface ``F = kappa delta integral_ellipse (1 - x^2/a^2 - y^2/b^2) dA
= kappa pi a b delta / 2``, so the nominal load F sets ``kappa = 2 F / (pi a b delta)``, and the
bed's stiffness is ``k_D = dF/d delta = kappa pi a b = 2 F / delta`` (Hertz's: 3 F / (2 delta)).

Linear filter. To first order in h the contact set stays the ellipse (w vanishes on its edge),
so at a fixed approach ``dF = kappa integral_ellipse h dA``: the roughness averaged uniformly
over the patch. For ``h = exp(i (q_x x + q_y y))`` the substitution x = a u, y = b v maps the
ellipse onto the unit disc, whose transform is ``2 pi J1(rho) / rho``, so

    dF / (k_D h) = 2 J1(rho) / rho,      rho = sqrt((q_x a)^2 + (q_y b)^2),

and the contact filter of a profile constant across the track is ``|H(q)|^2 = (2 J1(q a) / (q a))^2``
(:func:`transfer`). kappa cancels in the filter.

Rolling (:func:`roll`): the grid and positions of :func:`mdroll.bem.roll` (displacement
control, the decoupled mode): position s puts the lowest point of the indenter above the centre
of the window of rows ``start + s .. start + s + n - 1`` and the n middle columns; each spring is
a cell, compressed by w at its centre, ``F = kappa dx^2 sum max(w, 0)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import special

from ..errors import ParameterError
from .rolling import check_rolling
from .solver import array_module, to_host


@dataclass(frozen=True)
class Bed:
    """A DPRS bed (module docstring): Hertz's semi-axes ``semi_x`` a (along the track) and
    ``semi_y`` b (m), the approach ``delta`` (m) and the nominal ``load`` F (N)."""

    semi_x: float
    semi_y: float
    delta: float
    load: float

    def __post_init__(self):
        for name in ("semi_x", "semi_y", "delta", "load"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
                    or value <= 0:
                raise ParameterError(f"the DPRS bed's {name} must be a finite number > 0, got {value!r}")

    @property
    def kappa(self) -> float:
        """Stiffness per unit area, ``2 F / (pi a b delta)`` (N/m^3)."""
        return 2.0 * self.load / (math.pi * self.semi_x * self.semi_y * self.delta)

    @property
    def stiffness(self) -> float:
        """``k_D = kappa pi a b = 2 F / delta`` (N/m)."""
        return 2.0 * self.load / self.delta

    @property
    def radii(self) -> tuple[float, float]:
        """(R_x, R_y) of the gap ``z = x^2 / R_x + y^2 / R_y``: ``a^2 / delta``, ``b^2 / delta``
        (m); the wheel's radius for a sphere at Hertz's approach (its halved radius R/2 in
        ``x^2 / (2 (R/2))``)."""
        return self.semi_x**2 / self.delta, self.semi_y**2 / self.delta

    def as_dict(self) -> dict:
        return {**self.__dict__, "kappa": self.kappa, "stiffness": self.stiffness, "radii": list(self.radii)}


def transfer(qx, qy, semi_x: float, semi_y: float):
    """The linear DPRS transfer ``(2 J1(rho) / rho)^2``, ``rho = sqrt((q_x a)^2 + (q_y b)^2)``
    (module docstring; q in rad/m, broadcasting; q_y = 0 for a profile constant across the
    track). Dimensionless, 1 at rho = 0."""
    rho = np.sqrt((np.asarray(qx, dtype=np.float64) * semi_x) ** 2 + (np.asarray(qy, dtype=np.float64) * semi_y) ** 2)
    safe = np.where(rho == 0.0, 1.0, rho)
    return np.where(rho == 0.0, 1.0, (2.0 * special.j1(safe) / safe) ** 2)


def gap(n: int, dx: float, bed: Bed, xp=np):
    """The bed's undeformed gap z on the cell centres ``x_i = (i - (n - 1) / 2) dx`` of an n x n
    window, ``delta (x_i^2 / a^2 + y_j^2 / b^2)`` (m), in the array module ``xp``."""
    x = (np.arange(n) - 0.5 * (n - 1)) * dx
    return xp.asarray(bed.delta * (x[:, None] ** 2 / bed.semi_x**2 + x[None, :] ** 2 / bed.semi_y**2))


@dataclass
class BedRolling:
    """A DPRS rolling run: ``position`` (m, ``(steps,)``), ``force`` (N) and ``area`` (m^2, the
    cells in compression), (B, steps) or ``(steps,)`` for one surface, on the host."""

    position: np.ndarray
    force: np.ndarray
    area: np.ndarray


def roll(surface, dx: float, bed: Bed, *, steps: int, window: int | None = None, start: int = 0,
         device: str = "cpu") -> BedRolling:
    """The DPRS force at the fixed approach ``bed.delta`` at every position of the indenter
    rolled along axis 0 of ``surface`` (module docstring).

    Parameters
    ----------
    surface : (Lx, Ly) or (B, Lx, Ly) array, m
        Rough surface(s), positive up, cells of side ``dx`` (m); NumPy, or CuPy on CUDA.
    bed : Bed
    steps, window, start
        As :func:`mdroll.bem.roll`: positions, the window's side n (default Ly) and the row where
        the first window begins; ``start + steps - 1 + n <= Lx``.
    device : ``"cpu"`` (NumPy) or ``"cuda"`` / ``"cuda:N"`` (CuPy)

    Returns
    -------
    BedRolling
    """
    shape, n = check_rolling(surface, steps, window, start, smallest_window=1)
    if not isinstance(bed, Bed):
        raise ParameterError(f"bed must be a mdroll.bem.dprs.Bed, got {type(bed).__name__}")
    if isinstance(dx, bool) or not isinstance(dx, (int, float)) or not math.isfinite(dx) or dx <= 0:
        raise ParameterError(f"dx must be a finite number > 0, got {dx!r}")
    length, width = shape[-2:]
    first = (width - n) // 2
    xp, context = array_module(device)
    with context:
        full = xp.asarray(surface, dtype=xp.float64).reshape(-1, length, width)[:, :, first:first + n]
        reach = bed.delta - gap(n, dx, bed, xp)
        force = xp.empty((full.shape[0], steps))
        cells = xp.empty((full.shape[0], steps))
        for s in range(steps):
            w = reach + full[:, start + s:start + s + n, :]
            force[:, s] = xp.maximum(w, 0.0).sum(axis=(1, 2))
            cells[:, s] = (w > 0.0).sum(axis=(1, 2))
        force, area = to_host(force) * (bed.kappa * dx * dx), to_host(cells) * (dx * dx)
    if len(shape) == 2:
        force, area = force[0], area[0]
    return BedRolling(position=(start + np.arange(steps) + 0.5 * (n - 1)) * dx, force=force, area=area)
