"""The discretely supported rail: an infinite Timoshenko beam on identical supports at x_n = n d,
solved exactly as a periodic structure by Floquet (Bloch) superposition.

Choice and method: the free rail's Green's function ``G(x) = sum_j c_j exp(i k_j |x|)``
(:func:`mdroll.track.beam.green` with K_f = 0, ``c_j = i A_j / (2 k_j)``) is superposed with the
support forces. A unit force at x0 is the average over the Brillouin zone of Floquet loads
``sum_n z^n delta(x - x0 - n d)``, ``z = exp(i mu d)``, mu in [-pi/d, pi/d); each has support
forces ``R z^n`` with ``R = -K_s w(0)`` (K_s: :func:`mdroll.track.beam.support_stiffness`), so::

    w_z(x) = S(x - x0, z) - K_s S(-x0, z) S(x, z) / (1 + K_s S(0, z)),
    S(x, z) = sum_n z^n G(x - n d) = z^m sum_j c_j [exp(i k_j y) / (1 - e_j / z)
                                               + exp(-i k_j y) z e_j / (1 - z e_j)],

with ``x = m d + y``, 0 <= y < d, ``e_j = exp(i k_j d)`` (geometric series, |e_j| < 1). The
receptance ``alpha(x; x0)`` is the mean of w_z(x) over a uniform grid of mu (the trapezoid rule
of a smooth periodic integrand: exponentially convergent; :data:`ZONE_POINTS`). The free waves
of the periodic rail are the zeros of ``1 + K_s S(0, z)``: with ``S(0, z) = sum_j c_j (1 - e_j^2)
z / Q_j(z)``, ``Q_j = (z - e_j)(1 - e_j z)``, a quartic in z whose roots pair as (z, 1/z); the
least attenuated has the decay rate ``-20 log10|z| / d`` dB/m (Mead 1970's propagation constant).
References: Mead (1970), J. Sound Vib. 11; Thompson (2009), ch. 3; Heckl (2002), J. Sound Vib. 252.
"""

from __future__ import annotations

import numpy as np

from mdroll.physics import TWO_PI

from .beam import DB_PER_NEPER, support_stiffness, wavenumbers

#: Points of the Brillouin-zone average: the error of the trapezoid rule falls as |z_1|^N, with
#: |z_1| = 10^(-Delta d / 20) of the least attenuated free wave; 2048 give 1e-6 down to a decay
#: of Delta = 0.1 dB/m at d = 0.6 m.
ZONE_POINTS = 2048

#: Frequencies per block of :func:`discrete_receptance` (bounds its temporaries to ~50 MB).
CHUNK = 128


def free_waves(omega, track):
    """(c_j, k_j, e_j) of the free rail at omega (each of shape omega.shape + (2,))."""
    k, A = wavenumbers(omega, track, 0.0)
    return 0.5j * A / k, k, np.exp(1j * k * track.sleeper_spacing)


def lattice_sum(x, z, waves, spacing):
    """``S(x, z) = sum_n z^n G(x - n d)`` (m/N) of the free rail (module docstring).

    ``x`` (m, a scalar or shape (M,)), ``z`` (|z| = 1, shape (..., M)), ``waves`` from
    :func:`free_waves` with shape (..., 2); returns shape (..., M)."""
    m = np.floor(np.asarray(x, dtype=np.float64) / spacing)
    y = (x - m * spacing)[..., None]
    c, k, e = (w[..., None, :] for w in waves)
    zz = z[..., None]
    terms = c * (np.exp(1j * k * y) / (1.0 - e / zz) + np.exp(-1j * k * y) * zz * e / (1.0 - zz * e))
    return z**m * np.sum(terms, axis=-1)


def discrete_receptance(f, track, x0=0.0, x=None, zone_points=ZONE_POINTS):
    """Receptance of the discretely supported rail (m/N): displacement at ``x`` (m, default x0)
    per unit force at ``x0`` (m; 0 above a support, d/2 at mid-span), at frequencies ``f`` (Hz),
    by the Floquet superposition of the module docstring, averaged over ``zone_points`` mu
    (:data:`CHUNK` frequencies at a time)."""
    omega = TWO_PI * np.atleast_1d(np.asarray(f, dtype=np.float64)).ravel()
    x = x0 if x is None else x
    d = track.sleeper_spacing
    z = np.exp(1j * ((np.arange(zone_points) + 0.5) / zone_points * TWO_PI - np.pi))  # mu d on [-pi, pi)
    out = np.empty(omega.shape, dtype=complex)
    for start in range(0, len(omega), CHUNK):
        part = omega[start:start + CHUNK]
        waves = free_waves(part, track)
        zz = np.broadcast_to(z, part.shape + z.shape)
        K = support_stiffness(part, track)[:, None]
        w = lattice_sum(x - x0, zz, waves, d) - K * lattice_sum(-x0, zz, waves, d) * lattice_sum(x, zz, waves, d) / (
            1.0 + K * lattice_sum(0.0, zz, waves, d))
        out[start:start + CHUNK] = np.mean(w, axis=-1)
    return out.reshape(np.shape(f))


def _multipliers(omega, track):
    """The four Floquet multipliers at ``omega`` (rad/s, 1-D), sorted by |z|, with the free waves
    (:func:`free_waves`) and the support stiffness K_s: the roots of the quartic of
    :func:`floquet_multipliers` as the eigenvalues of its companion matrices, all at once."""
    waves = free_waves(omega, track)
    c, _, e = waves
    K = support_stiffness(omega, track)
    q1, q2 = (np.stack([-e[:, j], 1 + e[:, j] ** 2, -e[:, j]], axis=-1) for j in (0, 1))
    quartic = np.zeros((len(omega), 5), dtype=complex)
    for i in range(3):
        quartic[:, i:i + 3] += q1[:, i:i + 1] * q2
    w = c * (1 - e**2)
    quartic[:, 1:4] += K[:, None] * (w[:, :1] * q2 + w[:, 1:] * q1)
    companion = np.zeros((len(omega), 4, 4), dtype=complex)
    companion[:, 0, :] = -quartic[:, 1:] / quartic[:, :1]
    companion[:, 1, 0] = companion[:, 2, 1] = companion[:, 3, 2] = 1.0
    z = np.linalg.eigvals(companion)
    return np.take_along_axis(z, np.argsort(np.abs(z), axis=-1), axis=-1), waves, K


def floquet_multipliers(f, track):
    """The four Floquet multipliers z = exp(i mu d) of the free waves of the periodic rail at
    ``f`` (Hz): roots of ``Q_1 Q_2 + K_s z [c_1 (1 - e_1^2) Q_2 + c_2 (1 - e_2^2) Q_1] = 0``
    (module docstring), sorted by |z|. Returns shape f.shape + (4,)."""
    omega = TWO_PI * np.atleast_1d(np.asarray(f, dtype=np.float64)).ravel()
    return _multipliers(omega, track)[0].reshape(np.shape(f) + (4,))


def point_receptance(f, track, position="sleeper"):
    """Point receptance (m/N) above a support (``position="sleeper"``, x0 = 0) or at mid-span
    (``"midspan"``, x0 = d / 2) at ``f`` (Hz), in closed form: the zone average of the module
    docstring is the contour integral of ``w_z dz / (2 pi i z)`` around |z| = 1, whose poles
    inside are the two inner Floquet multipliers z_m (|z_m| < 1, :func:`floquet_multipliers`),
    the free waves' e_j, and z = 0. With ``S_0 = S(0, z)`` and ``S_0'`` its derivative::

        S_0'(z) = sum_j c_j [e_j / (1 - z e_j)^2 - e_j / (z - e_j)^2],
        sleeper:  alpha = - sum_m 1 / (K_s^2 z_m S_0'(z_m)),
        mid-span: alpha = - sum_m U(z_m)^2 / S_0'(z_m),
                  U(z) = S(d/2, z) / z = sum_j c_j a_j [1 / (z - e_j) + 1 / (1 - z e_j)],

    ``a_j = exp(i k_j d / 2)``. Above a support w_z = S_0 / (1 + K_s S_0) is finite at e_j and 0;
    at mid-span S(-d/2, z) = U(z) and the residues at e_j, -c_j, cancel the free rail's
    ``G(0) = sum_j c_j``. Equal to :func:`discrete_receptance` (its trapezoid rule converges to it)."""
    omega = TWO_PI * np.atleast_1d(np.asarray(f, dtype=np.float64)).ravel()
    z, (c, k, e), K = _multipliers(omega, track)
    z = z[:, :2, None]
    c, k, e = c[:, None, :], k[:, None, :], e[:, None, :]
    slope = np.sum(c * (e / (1 - z * e) ** 2 - e / (z - e) ** 2), axis=-1)
    if position == "sleeper":
        alpha = np.sum(-1.0 / (K[:, None] ** 2 * z[..., 0] * slope), axis=-1)
    else:
        u = np.sum(c * np.exp(0.5j * k * track.sleeper_spacing) * (1 / (z - e) + 1 / (1 - z * e)), axis=-1)
        alpha = np.sum(-(u**2) / slope, axis=-1)
    return alpha.reshape(np.shape(f))


def discrete_decay_rate(f, track):
    """Decay rate (dB/m) of the discretely supported rail: that of its least attenuated free
    wave, ``-20 log10|z| / d`` for the multiplier |z| < 1 nearest the unit circle
    (:func:`floquet_multipliers`). ``f`` in Hz."""
    z = floquet_multipliers(f, track)
    inside = np.where(np.abs(z) < 1.0, np.abs(z), 0.0)
    return -DB_PER_NEPER * np.log(np.max(inside, axis=-1)) / track.sleeper_spacing


def pinned_pinned_frequency(track):
    """Pinned-pinned frequency (Hz): the first bending mode of one bay of length d simply
    supported at both ends, with the wavenumber k = pi / d in the Timoshenko dispersion relation
    (P(k^2) = 0 with K_f = 0, module docstring of :mod:`mdroll.track.beam`), the lower root of::

        rho A rho I omega^4 - (kappa G A rho A + k^2 (E I rho A + kappa G A rho I)) omega^2
            + kappa G A E I k^4 = 0,

    exact for a simply supported Timoshenko span; ``(pi / (2 d^2)) sqrt(E I / rho A)`` in the
    Euler-Bernoulli limit (kappa G A -> inf, rho I = 0). Undamped."""
    k2 = (np.pi / track.sleeper_spacing) ** 2
    EI, m, GA, rI = track.rail_EI, track.rail_mass, track.rail_shear_stiffness, track.rail_rotary_inertia
    if np.isinf(GA):
        return np.sqrt(EI * k2**2 / (m + rI * k2)) / TWO_PI
    b = GA * m + k2 * (EI * m + GA * rI)
    c = GA * EI * k2**2
    if rI == 0:
        return np.sqrt(c / b) / TWO_PI
    omega2 = (b - np.sqrt(b * b - 4 * m * rI * c)) / (2 * m * rI)
    return np.sqrt(omega2) / TWO_PI
