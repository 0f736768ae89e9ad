"""The exact moving load over discrete supports, harmonic by harmonic: the Fourier coefficients of
the rail's steady-state deflection under a constant load moving along the periodic model of
:mod:`mdroll.track.periodic`, with its dynamics and losses (:func:`moving_harmonics`).

Choice and method: a wavenumber integral of closed forms, one integral for all harmonics at once
(they share the integrand's denominator, so its sharp peaks lie at the same wavenumbers for all),
by adaptive Gauss-Legendre quadrature. The peaks are the moving load meeting a free wave of the
periodic track (its Doppler-shifted frequency on a pass band): narrow where the track's losses are
small, which a uniform rule misses. :func:`mdroll.track.parametric.moving_load_deflection` gives
the same steady state at points of a bay by a second route (the Floquet loads in space, a uniform
rule) and checks it; :mod:`mdroll.track.parametric` makes the equivalent roughness of either.
"""

from __future__ import annotations

import numpy as np

from mdroll.errors import ParameterError

from .beam import support_stiffness
from .periodic import free_waves, lattice_sum

#: :func:`moving_harmonics`' quadrature: Gauss-Legendre nodes an interval, zones beyond the last
#: harmonic's, rounds of bisection at most, intervals at most (per zone), its relative tolerance,
#: the floor of its error scale (of the largest harmonic) and the wavenumbers evaluated at once.
MOVING_NODES = 8
MOVING_TAIL_ZONES = 60
MOVING_DEPTH = 60
MOVING_OPEN = 32
MOVING_RTOL = 1e-5
MOVING_FLOOR = 1e-9
BLOCK = 400


def check_discrete(track) -> None:
    """ParameterError unless ``track`` is discretely supported (a moving load over continuous or
    rigid support sees no bays)."""
    if track.support != "discrete":
        raise ParameterError(f"track.support = {track.support!r} has no sleeper bays: the moving load's "
                             "parametric excitation needs track.support = 'discrete'")


def moving_harmonics(track, speed: float, count: int, rtol: float = MOVING_RTOL) -> np.ndarray:
    """The Fourier coefficients ``c_n`` (m/N, complex, n = 1..count) of the rail's deflection under a
    unit load moving at ``speed`` (m/s), in the steady state, exact for the periodic model with its
    dynamics and losses: ``w(x) = c_0 + 2 Re sum_n c_n exp(2 pi i n x / d)`` under the load at x.

    The load ``delta(x - v t)`` is, at each frequency omega = v k, the force density
    ``exp(-i k x) / v``. The periodic rail answers it with a Floquet wave of the wavenumbers
    ``k_m = k + 2 pi m / d``: the free rail's ``G~(k) exp(-i k x)`` and the support forces' at the
    spacing, ``-K_s u_0 / d sum_m G~(k_m) exp(-i k_m x)``, ``u_0`` the rail's deflection at x = 0::

        G~(q) = sum_j 2 i c_j k_j / (k_j^2 - q^2)      (the free rail's receptance at wavenumber q),
        u_0 = G~(k) / (1 + K_s T),   T = (1 / d) sum_m G~(k_m) = S(0, exp(-i k d))

    (:func:`~mdroll.track.periodic.free_waves`; T is the lattice sum of
    :func:`~mdroll.track.periodic.lattice_sum` by Poisson's formula). Under the load (x = v t) the
    factor ``exp(-i k x) exp(i omega t)`` is 1, so the harmonic ``exp(-2 pi i m x / d)`` of w
    collects ``U_m(k) = -K_s u_0 G~(k_m) / d`` (m != 0) over k: ::

        c_n = (1 / 2 pi) integral_0^inf dk [U_{-n}(k) + conj(U_n(k))]

    (k < 0, negative frequencies, gives the complex conjugate). Quadrature: adaptive
    Gauss-Legendre (:func:`_adaptive_integral`, relative tolerance ``rtol`` on every harmonic)
    from the zones ``[j, j + 1] 2 pi / d``, j below ``count +`` :data:`MOVING_TAIL_ZONES`
    (U_{-n} peaks in zone n; beyond, the integrand falls as k^-4). A track with too little loss
    for its resonances under the moving load (an undamped one) has no steady state the rule
    reaches: a ParameterError naming its loss factors."""
    check_discrete(track)
    if not speed > 0:
        raise ParameterError(f"speed = {speed!r} m/s is not allowed: the moving load needs a positive speed")
    d = track.sleeper_spacing
    zone = 2.0 * np.pi / d
    m = np.concatenate([-np.arange(count, 0, -1), np.arange(1, count + 1)])

    def response(k):
        waves = free_waves(speed * k, track)
        K = support_stiffness(speed * k, track)
        T = lattice_sum(0.0, np.exp(-1j * k * d)[:, None], waves, d)[:, 0]
        u0 = free_receptance(k[:, None], waves)[:, 0] / (1.0 + K * T)
        return (-K * u0 / d)[:, None] * free_receptance(k[:, None] + zone * m, waves)

    U = _adaptive_integral(response, np.arange(count + MOVING_TAIL_ZONES + 1) * zone, rtol)
    if U is None:
        raise ParameterError(f"the moving load at speed = {speed!r} m/s has no steady state within rtol = {rtol:g} on "
                             f"this track: its losses (track.rail_loss = {track.rail_loss!r}, track.pad_loss = "
                             f"{track.pad_loss!r}, track.ballast_loss = {track.ballast_loss!r}) are too small for "
                             "its resonances under the moving load")
    U = U / (2.0 * np.pi)
    return U[count - 1::-1] + np.conj(U[count:])


def free_receptance(q, waves) -> np.ndarray:
    """The free rail's receptance at wavenumber ``q`` (rad/m, shape (B, Q)) and the frequencies of
    ``waves`` (:func:`~mdroll.track.periodic.free_waves`, shape (B, 2)): the Fourier transform of
    its Green's function ``sum_j c_j exp(i k_j |x|)``, ``sum_j 2 i c_j k_j / (k_j^2 - q^2)`` (m^2/N)."""
    c, k, _ = (w[:, None, :] for w in waves)
    return np.sum(2j * c * k / (k**2 - q[..., None] ** 2), axis=-1)


def _adaptive_integral(f, edges, rtol):
    """``integral f(k) dk`` over ``[edges[0], edges[-1]]`` of ``f`` (nodes (N,) -> values (N, H)),
    or None where it does not converge: Gauss-Legendre on each interval and on its two halves,
    whose difference is the interval's error, relative to every component's magnitude (held to
    :data:`MOVING_FLOOR` of the largest). While the errors add up to more than ``rtol``, every
    interval whose error exceeds an equal share of ``rtol`` is replaced by its halves (whose rules
    are known), so that an interval at a singular end point, whose error falls with its length,
    converges too: at most :data:`MOVING_DEPTH` rounds and :data:`MOVING_OPEN` intervals a
    starting one."""
    x, w = np.polynomial.legendre.leggauss(MOVING_NODES)

    def rule(lo, hi):
        nodes = (0.5 * (lo + hi))[:, None] + (0.5 * (hi - lo))[:, None] * x
        values = np.concatenate([f(block) for block in np.array_split(nodes.ravel(), -(-nodes.size // BLOCK))])
        return (0.5 * (hi - lo))[:, None] * np.einsum("ipk,p->ik", values.reshape(lo.size, x.size, -1), w)

    def bisect(a, b, whole):
        """The intervals' midpoints, the rule on their halves and their errors."""
        middle = 0.5 * (a + b)
        parts = rule(np.concatenate([a, middle]), np.concatenate([middle, b]))
        left, right = parts[:a.size], parts[a.size:]
        return middle, left, right, np.abs(left + right - whole)

    a, b = edges[:-1], edges[1:]
    middle, left, right, error = bisect(a, b, rule(a, b))
    for _ in range(MOVING_DEPTH):
        value = left + right
        scale = np.abs(np.sum(value, axis=0))
        scale = np.maximum(scale, MOVING_FLOOR * scale.max())
        relative = np.max(error / scale, axis=1)
        if relative.sum() <= rtol:
            return np.sum(value, axis=0)
        refine = relative > rtol / a.size
        if a.size + np.count_nonzero(refine) > MOVING_OPEN * (edges.size - 1):
            return None
        halves = (np.concatenate([a[refine], middle[refine]]), np.concatenate([middle[refine], b[refine]]))
        new = bisect(*halves, np.concatenate([left[refine], right[refine]]))
        keep = ~refine
        a, b = (np.concatenate([old[keep], part]) for old, part in zip((a, b), halves))
        middle, left, right, error = (np.concatenate([old[keep], part]) for old, part in
                                      zip((middle, left, right, error), new))
    return None
