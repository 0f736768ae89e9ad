"""The moving load over discrete supports: the rail's static receptance along a sleeper bay, and the
equivalent roughness of the parametric excitation at the sleeper-passing frequency, quasi-static
or exact at the run's speed (the rule of a run: always exact, below).

**Static receptance.** ``alpha_0(x)`` (m/N) is the rail's deflection under a static unit load at
``x`` (0 above a support, d/2 at mid-span), for the Timoshenko rail (:class:`~mdroll.track.Track`;
Euler-Bernoulli with ``rail_shear_stiffness = inf``) on identical supports at x_n = n d, each the
pad and the ballast in series, ``K_0 = k_p k_b / (k_p + k_b)``: the stated stiffnesses, elastic
(a static deflection has no loss; the complex moduli of the dynamic model,
:func:`mdroll.track.beam.modulus`, do not apply at omega = 0), and the sleeper mass does not
enter. It is solved directly and exactly: beam elements
with the exact static stiffness of a shear-deformable beam (nodal loads only, so the element is
exact; Przemieniecki 1968, *Theory of Matrix Structural Analysis*, ch. 5) on the bay [0, d] with
nodes at 0, x and d, and the semi-infinite rails on either side condensed into a 2x2 stiffness at
0 and at d: the fixed point of adding one bay and its support at a time
(:func:`semi_infinite_stiffness`).

**Equivalent roughness.** A wheel load F0 moving slowly along the rail rides on the deflected
rail, ``w(x) = F0 alpha_0(x)`` (downwards). Linearized about the static load, the contact point
of the model (the rail's dynamic receptance above a support, a stationary wheel) then sees the
roughness ::

    r_p(x) = -F0 (alpha_0(x) - <alpha_0>),    <alpha_0> = (1/d) integral_0^d alpha_0 dx,

heights positive towards the wheel like the roughness of physics.md section 2 (u_i = h_i + d -
...): where the rail deflects more (mid-span) the rail head lies lower. The mean is the static
deflection, absorbed in the static equilibrium. The product of the receptance's variation with
the force's fluctuation is of second order (neglected). r_p is periodic in d, so it excites at
the sleeper-passing frequency v/d and its harmonics n v/d.

**Assumption** (quasi-static): the load moves slowly against the track's waves, so that the
rail's deflection under it follows the static shape of the stated, elastic stiffnesses. r_p is
that elastic limit, not the slow limit of the dynamic track: neither damping model tends to the
elastic, lossless stiffness at low frequency (the causal moduli soften below
``track.damping_frequency`` as (f / f_r)^p, the hysteretic ones keep their loss), so no
frequency bounds where r_p stands for the dynamic track at speed, and none is offered
(docs/track.md gives the exact line against r_p per preset and speed).

**The exact moving load** (:func:`mdroll.track.moving.moving_harmonics`): the steady state of the
periodic model of :mod:`mdroll.track.periodic` under a constant load at speed v, with its dynamics
and losses, as the Fourier coefficients of the deflection under the load, harmonic by harmonic;
:func:`moving_load_deflection` gives the same deflection at points of the bay by a second route
(the Floquet loads in space) and checks it. Its equivalent roughness is ``r(x) = -(w(x; v) - <w>)``,
w the deflection under F0 (:func:`moving_bay_roughness`).

**The rule of a run: always the exact line**, at the run's speed (``speed`` of
:func:`equivalent_roughness`, :func:`harmonics`, :func:`roughness_levels`; None gives the
quasi-static line). It is a wavenumber integral of closed forms, made once a (track, speed) and
cheap beside a run (docs/track.md gives its cost), so a switch to the quasi-static line at low
speeds would save little, and one rule keeps (1) one model of the track: the line follows the
same support stiffness, damping included, as the receptances the run steps, where the
quasi-static line takes the elastic stiffness, which neither damping model tends to at low
frequency; (2) no jump in a run's results at a switching speed.
The exact line holds the first :data:`MOVING_HARMONICS` harmonics and leaves out the rest: the
harmonics fall as 1/n^2 (the kink of the deflection above a support), and wavelengths below d / 64
lie at or beyond the first zero of the contact filter of a thesis-sized contact (2a = 10 mm).
"""

from __future__ import annotations

import functools

import numpy as np

from mdroll.errors import ParameterError
from mdroll.roughness.bands import band_centres, wavelength_band_edges_q

from .beam import support_stiffness
from .moving import check_discrete, moving_harmonics
from .periodic import free_waves, lattice_sum

#: Samples of the line over one bay (:func:`bay_roughness`) for :func:`equivalent_roughness`
#: (periodic linear interpolation between them) and :func:`harmonics` (their discrete Fourier
#: transform).
BAY_POINTS = 1024
#: Bays added one at a time at most to the semi-infinite rail of :func:`semi_infinite_stiffness`
#: (it stops when the stiffness no longer changes: after 19-22 for the presets).
MAX_BAYS = 10_000
#: Reference of roughness levels: 1 um (dB re 1 um).
ROUGHNESS_REFERENCE = 1e-6
#: :func:`moving_load_deflection`'s quadrature: wavenumbers (midpoint rule) up to this many
#: times 2 pi / d, their count, source positions over a bay (trapezoid rule) and wavenumbers a block.
MOVING_BAYS = 120
MOVING_WAVENUMBERS = 6000
MOVING_SOURCES = 256
MOVING_BLOCK = 400
#: Harmonics of the exact line (:func:`moving_bay_roughness`): wavelengths down to d / 64.
MOVING_HARMONICS = 64


def element_stiffness(length, track):
    """Exact static stiffness matrices (shape ``length.shape + (4, 4)``) of rail elements of
    ``length`` (m), degrees of freedom (w_1, theta_1, w_2, theta_2): the shear-deformable beam with
    ``Phi = 12 E I / (kappa G A L^2)`` (0 for Euler-Bernoulli)::

        E I / ((1 + Phi) L^3) [[12, 6L, -12, 6L], [6L, (4 + Phi) L^2, -6L, (2 - Phi) L^2],
                               [-12, -6L, 12, -6L], [6L, (2 - Phi) L^2, -6L, (4 + Phi) L^2]]

    exact for loads at the nodes (Przemieniecki 1968, ch. 5)."""
    L = np.asarray(length, dtype=np.float64)
    EI = track.rail_EI
    phi = 12.0 * EI / (track.rail_shear_stiffness * L**2)
    L2 = L**2
    rows = [[12 + 0 * L, 6 * L, -12 + 0 * L, 6 * L],
            [6 * L, (4 + phi) * L2, -6 * L, (2 - phi) * L2],
            [-12 + 0 * L, -6 * L, 12 + 0 * L, -6 * L],
            [6 * L, (2 - phi) * L2, -6 * L, (4 + phi) * L2]]
    return (EI / ((1 + phi) * L**3))[..., None, None] * np.moveaxis(np.array(rows), (0, 1), (-2, -1))


def support_static_stiffness(track) -> float:
    """Static stiffness of one support (N/m): the pad in series with the ballast, elastic."""
    return track.pad_stiffness * track.ballast_stiffness / (track.pad_stiffness + track.ballast_stiffness)


def semi_infinite_stiffness(track) -> np.ndarray:
    """2x2 static stiffness (w, theta) at the end node of the semi-infinite rail to its left, with
    every support to the left of that node but not the one at it: the fixed point of
    ``D <- condense(element(d) with D + diag(K_0, 0) at its far node)``, from a free end (D = 0),
    bay by bay until it changes by less than 1e-14 of itself (at most :data:`MAX_BAYS`)."""
    k = element_stiffness(track.sleeper_spacing, track)
    spring = np.diag([support_static_stiffness(track), 0.0])
    D = np.zeros((2, 2))
    for _ in range(MAX_BAYS):
        far = k[:2, :2] + D + spring
        new = k[2:, 2:] - k[2:, :2] @ np.linalg.solve(far, k[:2, 2:])
        if np.max(np.abs(new - D)) <= 1e-14 * np.max(np.abs(new)):
            return new
        D = new
    raise ArithmeticError("the semi-infinite rail's stiffness did not converge")


def static_receptance(track, x) -> np.ndarray:
    """Static receptance ``alpha_0(x)`` (m/N) of the discretely supported rail: its deflection at
    ``x`` (m, any shape; taken modulo the sleeper spacing d) under a unit load at ``x`` (module
    docstring). Vectorized: one 6x6 system per position (4x4 above a support)."""
    check_discrete(track)
    d = track.sleeper_spacing
    x = np.mod(np.asarray(x, dtype=np.float64), d)
    left = semi_infinite_stiffness(track)
    mirror = np.diag([1.0, -1.0])
    right = mirror @ left @ mirror
    spring = np.diag([support_static_stiffness(track), 0.0])
    out = np.empty(x.shape)
    above = (x == 0.0)
    # above a support: nodes 0 and d
    K = element_stiffness(d, track).copy()
    K[:2, :2] += left + spring
    K[2:, 2:] += right + spring
    out[above] = np.linalg.solve(K, np.array([1.0, 0.0, 0.0, 0.0]))[0]
    inside = x[~above]
    if inside.size:
        K = np.zeros(inside.shape + (6, 6))
        K[..., :4, :4] += element_stiffness(inside, track)
        K[..., 2:, 2:] += element_stiffness(d - inside, track)
        K[..., :2, :2] += left + spring
        K[..., 4:, 4:] += right + spring
        load = np.zeros(inside.shape + (6, 1))
        load[..., 2, 0] = 1.0
        out[~above] = np.linalg.solve(K, load)[..., 2, 0]
    return out


def bay_receptance(track, points: int = BAY_POINTS) -> tuple[np.ndarray, np.ndarray]:
    """``(x, alpha_0(x))`` on ``points`` uniform positions ``x_j = j d / points`` of one bay (m, m/N)."""
    x = np.arange(points) * (track.sleeper_spacing / points)
    return x, static_receptance(track, x)


def bay_roughness(track, load: float, speed=None) -> np.ndarray:
    """The equivalent roughness (m) on :data:`BAY_POINTS` uniform positions ``x_j = j d / BAY_POINTS``
    of one bay under the wheel load ``load`` = F0 (N): the quasi-static ``-F0 (alpha_0 - <alpha_0>)``
    (``speed`` None) or the exact moving load's at ``speed`` (m/s, :func:`moving_bay_roughness`)."""
    if speed is None:
        _, alpha = bay_receptance(track)
        return -load * (alpha - alpha.mean())
    return load * moving_bay_roughness(track.structure(), float(speed))


@functools.lru_cache(maxsize=16)
def moving_bay_roughness(track, speed: float) -> np.ndarray:
    """The exact moving load's equivalent roughness per newton (m/N) on the positions of
    :func:`bay_roughness`: ``-(w - <w>)``, w the deflection of the first :data:`MOVING_HARMONICS`
    harmonics of :func:`moving_harmonics` summed at each position, computed once a (track, speed)
    and kept (read-only)."""
    n = np.arange(1, MOVING_HARMONICS + 1)
    phase = np.exp(2j * np.pi * np.outer(np.arange(BAY_POINTS), n) / BAY_POINTS)
    line = -2.0 * (phase @ moving_harmonics(track, speed, MOVING_HARMONICS)).real
    line.flags.writeable = False
    return line


def equivalent_roughness(track, load: float, x, speed=None) -> np.ndarray:
    """The equivalent roughness (m) of the wheel load ``load`` = F0 (N) at positions ``x`` (m, any
    shape; 0 above a support): quasi-static, ``r_p(x) = -F0 (alpha_0(x) - <alpha_0>)`` (``speed``
    None), or the exact moving load's at ``speed`` (m/s), ``-(w(x) - <w>)``; heights positive
    towards the wheel (module docstring). Interpolated linearly and periodically between the
    :data:`BAY_POINTS` samples of :func:`bay_roughness`, whose mean is zero."""
    d = track.sleeper_spacing
    line = bay_roughness(track, load, speed)
    grid = np.arange(BAY_POINTS + 1) * (d / BAY_POINTS)
    return np.interp(np.mod(np.asarray(x, dtype=np.float64), d), grid, np.append(line, line[0]))


def harmonics(track, load: float, count: int = 32, speed=None) -> tuple[np.ndarray, np.ndarray]:
    """The line spectrum of :func:`equivalent_roughness` (quasi-static, or exact at ``speed``):
    ``(wavelength_m, rms_m)`` of its harmonics n = 1..count, wavelength d / n and RMS
    ``sqrt(2) |c_n|``, c_n the Fourier coefficients of the line over a bay (of the samples of
    :func:`bay_roughness`; count below half of them, and at most :data:`MOVING_HARMONICS` with a
    speed). At speed v harmonic n lies at the frequency ``n v / d``."""
    top = BAY_POINTS // 2 - 1 if speed is None else MOVING_HARMONICS
    if not 1 <= count <= top:
        raise ParameterError(f"count = {count!r} is not allowed: 1 to {top} harmonics")
    c = np.fft.rfft(bay_roughness(track, load, speed)) / BAY_POINTS
    n = np.arange(1, count + 1)
    return track.sleeper_spacing / n, np.sqrt(2.0) * np.abs(c[n])


def roughness_levels(track, load: float, wavelengths_mm, speed=None) -> np.ndarray:
    """1/3-octave levels (dB re 1 um) of the equivalent roughness (quasi-static, or exact at
    ``speed``) in the wavelength bands of nominal centres ``wavelengths_mm`` (mm), as the roughness
    tables give them (:mod:`mdroll.roughness.bands`: band n holds the wavenumbers
    ``q_lo <= q < q_hi``): the mean square of the harmonics in each band; ``-inf`` where a band
    holds none; NaN, with a speed, where it may hold one beyond the exact line's
    :data:`MOVING_HARMONICS`."""
    wavelengths_mm = np.asarray(wavelengths_mm, dtype=np.float64)
    q_lo, q_hi = wavelength_band_edges_q(np.rint(10.0 * np.log10(wavelengths_mm)).astype(np.int64))
    shortest = band_centres(np.rint(10.0 * np.log10(wavelengths_mm.min())) - 1) * 1e-3
    count = min(BAY_POINTS // 2 - 1, int(np.ceil(track.sleeper_spacing / shortest)))
    if speed is not None:
        count = min(count, MOVING_HARMONICS)
    wavelength, rms = harmonics(track, load, count, speed)
    q = 2.0 * np.pi / wavelength
    inside = (q[None, :] >= q_lo[:, None]) & (q[None, :] < q_hi[:, None])
    mean_square = np.sum(np.where(inside, rms[None, :] ** 2, 0.0), axis=1)
    with np.errstate(divide="ignore"):
        levels = 10.0 * np.log10(mean_square / ROUGHNESS_REFERENCE**2)
    if speed is not None:
        levels[q_hi > 2.0 * np.pi * (MOVING_HARMONICS + 1) / track.sleeper_spacing] = np.nan
    return levels


def sleeper_passing_frequency(track, speed: float) -> float:
    """The sleeper-passing frequency v / d (Hz) at ``speed`` (m/s)."""
    return speed / track.sleeper_spacing


def moving_load_deflection(track, load: float, speed: float, x) -> np.ndarray:
    """The rail's deflection (m) under a constant load ``load`` (N) moving at ``speed`` (m/s) when
    the load is at ``x`` (m, shape (P,)), in the steady state, exact for the periodically supported
    rail of :mod:`mdroll.track.periodic` with its dynamics and losses (no quasi-static assumption).

    The load ``F0 delta(x - v t)`` is, at each frequency omega, the force density
    ``(F0 / v) exp(-i k xi)``, k = omega / v; gathered by bays it is the Floquet loads
    ``z^n`` at ``xi + n d``, ``z = exp(-i k d)``, whose response ``w_z(x; xi)`` is the periodic
    model's. Under the load (x = v t)::

        w(x) = (F0 / pi) Re integral_0^inf dk exp(i k x) integral_0^d dxi exp(-i k xi) w_z(x; xi, omega = v k)

    (k < 0 gives the complex conjugate). Quadrature: the midpoint rule in k up to
    :data:`MOVING_BAYS` times 2 pi / d with :data:`MOVING_WAVENUMBERS` points, the trapezoid rule
    over :data:`MOVING_SOURCES` intervals of xi. As the speed tends to zero it tends to
    ``F0 alpha_0(x)`` with the receptance's loss factors (:func:`static_receptance` without them)."""
    check_discrete(track)
    d = track.sleeper_spacing
    x = np.atleast_1d(np.asarray(x, dtype=np.float64))
    k_top = MOVING_BAYS * 2.0 * np.pi / d
    dk = k_top / MOVING_WAVENUMBERS
    xi = np.linspace(0.0, d, MOVING_SOURCES + 1)
    weight = np.full(xi.shape, d / MOVING_SOURCES)
    weight[[0, -1]] *= 0.5
    out = np.zeros(x.shape)
    for start in range(0, MOVING_WAVENUMBERS, MOVING_BLOCK):
        k = (np.arange(start, min(start + MOVING_BLOCK, MOVING_WAVENUMBERS)) + 0.5) * dk
        omega = speed * k
        waves = free_waves(omega, track)
        K = support_stiffness(omega, track)[:, None]
        z = np.broadcast_to(np.exp(-1j * k * d)[:, None], (k.size, xi.size))
        at_support = lattice_sum(0.0, z[:, :1], waves, d)
        phase = np.exp(-1j * k[:, None] * xi) * weight
        from_supports = K * lattice_sum(-xi, z, waves, d) / (1.0 + K * at_support)
        for i, position in enumerate(x):
            response = lattice_sum(position - xi, z, waves, d) - from_supports * lattice_sum(position, z[:, :1], waves, d)
            out[i] += np.sum(np.exp(1j * k * position) * np.sum(phase * response, axis=1)).real
    return load * dk / np.pi * out

