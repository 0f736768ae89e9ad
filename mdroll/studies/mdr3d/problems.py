"""The problems of the MDR-against-3-D study: an indenter at a load, the grid both models share,
the surfaces of a case (reproducible from (seed, index)), the MDR lines of each variant and the
two forces at the same positions.

Geometry (docs/bem.md): axis 0 of a surface runs along the track, cells of side dx; the 3-D
indenter is the paraboloid of radii R_x (the wheel) by R_y (the rail crown; R_y = R_x for the
sphere), held at the fixed approach that carries the load on a smooth surface (the decoupled
mode, displacement control). Its contact stiffness is ``k = dF/dd = 3 F / (2 d)`` (Hertz, F ~ d^(3/2)
for any ellipse) and its semi-axis along the track a_x. Position s of a rolling run puts the
indenter's lowest point above row ``s + (n - 1) / 2`` of the surface (n odd, the window), so the
MDR wheel of the same position stands on spring ``s + (n - 1) / 2`` of the line: the two forces
are series over the same positions.

The MDR variants (each a sphere on a row of springs, eq 10-12, at its own fixed approach):

* ``mdr``: today's MDR, the sphere of the wheel radius R_x at the load, same E*; its line is the
  profile itself for a corrugation (a), and for isotropic or anisotropic surfaces (b, c) an
  independent MDR line of the mapped spectrum (Geike's rule: same H, q_min and RMS, eq 33);
* ``line``: the sphere of the wheel radius on the surface's own centre line, the line a roughness
  trolley measures (the rail assumption, C_1D = C_p);
* ``corrected``: the sphere matched to the 3-D contact, radius ``R_c = 4 E_c a_x^3 / (3 F)`` and
  modulus ``E_c = k / (2 a_x)`` (so its contact half-length is a_x and its stiffness k), on the
  surface averaged uniformly across the contact width ``|y| <= a_y``. To first order in the
  roughness a 3-D contact's force is the roughness weighted by the flat-punch pressure of its
  ellipse; across the track that weight integrates to a constant on ``|x| < a_x`` (so a
  corrugation sees the MDR's uniform line weight of half-length a_x), and along the track to a
  constant on ``|y| < a_y`` (so roughness constant along the track sees the uniform lateral
  mean). The corrected MDR is exact on both axes of the wavenumber plane (linear order).

Beside them the distributed point-reacting spring bed (:mod:`mdroll.bem.dprs`) of Hertz's
ellipse, at the 3-D approach and the load, rolls on the 3-D surfaces themselves (:func:`dprs_forces`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ... import physics, rough_lines
from ...bem import extruded, hertz_elliptical, roll, self_affine
from ...bem import dprs
from ...devices import array_module, is_cuda
from ...ensemble.psd import array_rows, to_host
from ...forces.force import contact_force
from ...params import Params

#: Poisson's ratio of both bodies (steel); E* is the study's, E = 2 (1 - nu^2) E* (eq 1-2).
NU = 0.3
#: Surfaces: (a) a profile extruded across the track, (b) isotropic, (c) anisotropic.
SURFACES = ("a", "b", "c")
#: The 3-D indenters: the sphere of the wheel radius and the wheel-by-crown ellipsoid.
INDENTERS = ("sphere", "ellipse")
#: The MDR variants compared with the 3-D reference (module docstring).
VARIANTS = ("mdr", "line", "corrected")
#: Springs of the MDR line per cell of the 3-D grid (odd, so that a_x stays half a spring beyond the
#: last spring, see :func:`grid`). The MDR's contact edge moves spring by spring: the edge spring
#: sits at the indentation d dx_MDR / a, and eq 48's edge force needs the roughness to move it, so
#: the line resolves the contact with a few hundred springs (the 3-D grid's cells are far fewer).
MDR_REFINE = 15
#: The window's side as a multiple of the contact length 2 a_x: room for a rough contact's spread
#: (at h0 = 0.1 d0 a crest three RMS high widens the contact by about 14 %).
WINDOW_MARGIN = 1.25


@dataclass(frozen=True)
class Geometry:
    """An indenter at a load: 3-D radii (m), load (N), E* (Pa), and what follows from Hertz:
    approach (m), semi-axes a_x, a_y (m), stiffness k (N/m); the MDR sphere of the wheel radius
    (approach ``mdr_approach``, m) and the corrected sphere (``corrected_radius`` m,
    ``corrected_modulus`` Pa, ``corrected_approach`` m)."""

    name: str
    radius_x: float
    radius_y: float
    load: float
    E_star: float
    approach: float
    semi_x: float
    semi_y: float
    stiffness: float
    mdr_approach: float
    corrected_modulus: float
    corrected_radius: float
    corrected_approach: float

    def as_dict(self) -> dict:
        return dict(self.__dict__)


def geometry(name: str, wheel_radius: float, crown_radius: float, load: float, E_star: float) -> Geometry:
    """The :class:`Geometry` of indenter ``name`` ("sphere": R_x = R_y = the wheel radius;
    "ellipse": R_x the wheel radius, R_y the crown radius) at ``load`` (N)."""
    radius_y = wheel_radius if name == "sphere" else crown_radius
    probe = 1e-5  # any approach: Hertz's F ~ d^(3/2) scales it to the load
    force = hertz_elliptical(probe, E_star, wheel_radius, radius_y)[3]
    approach = probe * (load / force) ** (2.0 / 3.0)
    semi_x, semi_y, _, _ = hertz_elliptical(approach, E_star, wheel_radius, radius_y)
    stiffness = 1.5 * load / approach
    modulus = stiffness / (2.0 * semi_x)
    radius = 4.0 * modulus * semi_x**3 / (3.0 * load)
    return Geometry(name, wheel_radius, radius_y, load, E_star, approach, semi_x, semi_y, stiffness,
                    float(physics.hertz_indentation(load, E_star, wheel_radius)), modulus, radius,
                    semi_x * semi_x / radius)


@dataclass(frozen=True)
class Grid:
    """The cells both models share: side ``dx`` (m), window ``n`` (odd) cells, ``positions``
    rolling positions, surfaces of ``length`` x ``n`` cells, cut from the middle of surfaces
    generated ``width`` cells wide (odd; wide enough to sample the spectrum across the track)."""

    dx: float
    n: int
    positions: int
    length: int
    width: int

    @property
    def centre(self) -> int:
        """The column of the window's centre line, and the row of position 0's lowest point."""
        return (self.n - 1) // 2

    def as_dict(self) -> dict:
        return dict(self.__dict__)


def _odd(value: float) -> int:
    k = int(math.ceil(value))
    return k if k % 2 else k + 1


def grid(shape: Geometry, cells: int, positions: int, q_min: float) -> Grid:
    """The grid of an indenter: ``cells`` across the contact length 2 a_x, a window of
    :data:`WINDOW_MARGIN` times that, ``positions`` positions, and a surface wide enough that the
    lateral wavenumber step is at most q_min / 4 (q_min the smallest cut-off of the cases, rad/m).

    An odd ``cells`` puts a_x half a cell beyond the last spring of an MDR of half-length a_x, so
    no spring sits at zero indentation: a spring there would switch with the sign of the
    roughness and rectify it into spurious low-band force."""
    dx = 2.0 * shape.semi_x / cells
    n = _odd(WINDOW_MARGIN * cells)
    width = max(n, _odd(8.0 * math.pi / (q_min * dx)))
    return Grid(dx, n, positions, positions + n - 1, width)


@dataclass(frozen=True)
class Case:
    """One problem of the study: surface ("a", "b" or "c"), indenter, Hurst exponent H, RMS
    roughness over the 3-D approach ``h0_d0``, cut-off times a_x ``qmin_a``, and the anisotropy
    gamma of surface (c)."""

    surface: str
    indenter: str
    H: float
    h0_d0: float
    qmin_a: float
    anisotropy: float = 1.0

    def label(self) -> str:
        return f"({self.surface}) {self.indenter} H {self.H:g} h0/d0 {self.h0_d0:g} q_min a {self.qmin_a:g}"


def line_params(shape: Geometry, mesh: Grid, case: Case, variant: str = "mdr", refine: int = 1) -> Params:
    """The MDR's :class:`~mdroll.params.Params` of a case: the line of ``mesh.length`` cells of
    dx, ``refine`` springs a cell, the roughness of the case (RMS ``h0_d0`` times the 3-D approach,
    H, q_min = qmin_a / a_x), the sphere and modulus of ``variant`` at the load."""
    modulus, radius = ((shape.corrected_modulus, shape.corrected_radius) if variant == "corrected"
                       else (shape.E_star, shape.radius_x))
    return Params(E=2.0 * (1.0 - NU * NU) * modulus, nu=NU, R=radius, F_N=shape.load, L=mesh.length * mesh.dx,
                  dx=mesh.dx / refine, h0=case.h0_d0 * shape.approach, H=case.H, q_min=case.qmin_a / shape.semi_x)


def surfaces(shape: Geometry, mesh: Grid, case: Case, seed: int, indices, device: str):
    """The (B, length, n) surfaces of a case (m; NumPy, or CuPy on CUDA): (a) the MDR lines of
    the case (:func:`mdroll.rough_lines`) extruded across the track, (b) and (c) the middle n
    columns of :func:`mdroll.bem.self_affine` surfaces ``width`` cells wide with the case's H,
    q_min and RMS (anisotropy gamma for (c))."""
    p = line_params(shape, mesh, case)
    if case.surface == "a":
        lines = to_host(array_rows(rough_lines(p, seed, indices, device=device), device))
        return on_device(extruded(lines, mesh.n), device)
    full = self_affine((mesh.length, mesh.width), mesh.dx, H=case.H, q_min=p.q_min, rms=p.h0, seed=seed,
                       indices=list(indices), anisotropy=case.anisotropy if case.surface == "c" else 1.0,
                       device=device)
    first = (mesh.width - mesh.n) // 2
    return full[:, :, first:first + mesh.n].copy()


def on_device(array, device: str):
    """``array`` (NumPy) on ``device``: itself on the CPU, a CuPy copy on CUDA."""
    if is_cuda(device):
        import cupy  # lazily: CUDA runs only

        with cupy.cuda.Device(int(device.partition(":")[2] or 0)):
            return cupy.asarray(array)
    return array


def variant_lines(shape: Geometry, mesh: Grid, case: Case, heights, seed: int, indices, variant: str, device: str):
    """The (B, length) MDR lines of ``variant`` (module docstring) for the surfaces ``heights``."""
    if variant == "mdr" and case.surface != "a":
        return rough_lines(line_params(shape, mesh, case), seed, indices, device=device)
    if variant == "corrected":
        half = int(math.floor(shape.semi_y / mesh.dx))
        return heights[:, :, mesh.centre - half:mesh.centre + half + 1].mean(axis=2)
    return heights[:, :, mesh.centre]


def refined(lines, refine: int, device: str):
    """The periodic lines (B, L) on ``refine`` times finer a grid, by band-limited (Fourier)
    interpolation: the same spectrum, the same values at the old points (NumPy, or CuPy on CUDA)."""
    lines = array_rows(lines, device)
    xp = array_module(lines)
    count = lines.shape[-1]
    spectrum = xp.fft.rfft(lines, axis=-1)
    if count % 2 == 0:  # the old Nyquist mode is a cosine: half of it at +q, half at -q
        spectrum[:, -1] *= 0.5
    padded = xp.zeros((lines.shape[0], refine * count // 2 + 1), dtype=spectrum.dtype)
    padded[:, :spectrum.shape[1]] = spectrum
    return xp.fft.irfft(padded, refine * count, axis=-1) * refine


def mdr_forces(shape: Geometry, mesh: Grid, case: Case, lines, variant: str, device: str,
               refine: int = MDR_REFINE) -> np.ndarray:
    """The MDR force (B, positions) (N) of ``lines`` (on the 3-D grid) at the rolling positions:
    the lines refined to ``refine`` springs a cell (:func:`refined`), the sweep (exact, eq 10-12) on
    the periodic line at the variant's fixed approach, read at the springs of cells
    ``(n - 1) / 2 + s``, where the contact never reaches the line's ends."""
    p = line_params(shape, mesh, case, variant, refine)
    d = shape.corrected_approach if variant == "corrected" else shape.mdr_approach
    fine = refined(lines, refine, device)
    force = to_host(array_rows(contact_force(fine, p, "sweep", "periodic", d=d, device=device), device))
    return force[:, mesh.centre * refine:(mesh.centre + mesh.positions) * refine:refine]


def bem_forces(shape: Geometry, mesh: Grid, heights, device: str, tol: float):
    """The 3-D force (B, positions) (N) by quasi-static rolling (:func:`mdroll.bem.roll`) at the
    approach that carries the load on a smooth surface; the run's iteration counts and whether
    every solve converged (both (B, positions))."""
    run = roll(heights, mesh.dx, shape.radius_x, radius_y=shape.radius_y, E_star=shape.E_star, steps=mesh.positions,
               approach=shape.approach, window=mesh.n, device=device, tol=tol)
    return run.force, run.iterations, run.converged


def bed(shape: Geometry) -> dprs.Bed:
    """The DPRS bed of an indenter (:mod:`mdroll.bem.dprs`): Hertz's ellipse, the 3-D approach
    and the load, so that the bed's smooth static contact is the 3-D one."""
    return dprs.Bed(float(shape.semi_x), float(shape.semi_y), float(shape.approach), float(shape.load))


def dprs_forces(shape: Geometry, mesh: Grid, heights, device: str) -> np.ndarray:
    """The DPRS force (B, positions) (N) on the 3-D reference's surfaces and positions, at the 3-D
    approach (:func:`mdroll.bem.dprs.roll`)."""
    return dprs.roll(heights, mesh.dx, bed(shape), steps=mesh.positions, window=mesh.n, device=device).force


def centre_profiles(mesh: Grid, heights) -> np.ndarray:
    """The surfaces' centre lines under the indenter at the positions (B, positions) (m, host):
    the roughness the contact filter is referred to (what a trolley measures)."""
    return to_host(heights[:, mesh.centre:mesh.centre + mesh.positions, mesh.centre])
