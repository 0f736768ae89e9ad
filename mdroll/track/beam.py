"""The Timoshenko rail on a continuous two-layer foundation: wavenumbers, Green's function,
point receptance and decay rate (closed forms, vectorized over frequency).

Time dependence ``exp(i omega t)``; a receptance is displacement per force, alpha = w / F (m/N),
with a negative imaginary part where the system dissipates. A stiffness k with loss factor eta
becomes the complex modulus k*(omega) of :func:`modulus`: by default the causal constant-loss
(constant-Q) modulus of Kjartansson (1979), or the hysteretic ``k (1 + i eta)``. References:
Grassie, Gregory, Harrison & Johnson (1982), "The dynamic response of railway track to high
frequency vertical excitation", J. Mech. Eng. Sci. 24; Knothe & Grassie (1993), "Modelling of
railway track and vehicle/track interaction at high frequencies", Vehicle System Dynamics 22;
Thompson (2009), *Railway Noise and Vibration*, ch. 3.

The beam (deflection w, rotation phi, foundation stiffness per length K_f(omega))::

    kappa G A (w'' - phi') + rho A omega^2 w - K_f w = -F delta(x)
    E I phi'' + kappa G A (w' - phi) + rho I omega^2 phi = 0

In the wavenumber domain (``w(x) = integral W(k) exp(i k x) dk / (2 pi)``) W = F D(k^2) / P(k^2)::

    D(s) = E I s + kappa G A - rho I omega^2
    P(s) = kappa G A E I s^2 - (kappa G A rho I omega^2 + E I (rho A omega^2 - K_f)) s
           - (rho A omega^2 - K_f) (kappa G A - rho I omega^2)

whose two roots s_j = k_j^2 give the Green's function by residues (Im k_j > 0, decaying away
from the force): ``G(x) = (i / 2) sum_j A_j exp(i k_j |x|) / k_j`` with
``A_j = D(s_j) / (kappa G A E I (s_j - s_other))``. With kappa G A -> inf and rho I = 0 it is the
Euler-Bernoulli beam ``E I k^4 = rho A omega^2 - K_f``.
"""

from __future__ import annotations

import numpy as np

from mdroll.physics import TWO_PI

#: dB per neper of amplitude, 20 log10(e): a wave exp(i k x) decays by DB_PER_NEPER Im(k) dB/m.
DB_PER_NEPER = 20.0 / np.log(10.0)


def modulus(k, eta, omega, track):
    """The complex modulus k*(omega) of a stiffness ``k`` (N/m, N m^2 or N) with loss factor ``eta``
    under ``track.damping`` (:data:`~mdroll.track.parameters.DAMPINGS`), as an array of omega's
    shape (rad/s)::

        causal:      k* = k (1 + i eta) (|omega| / omega_r)^p,   p = (2 / pi) arctan(eta),
        hysteretic:  k* = k (1 + i eta),

    omega_r = 2 pi ``track.damping_frequency``. The causal modulus is Kjartansson's (1979,
    "Constant Q-wave propagation and attenuation", J. Geophys. Res. 84(B9)) constant-loss model,
    ``k sqrt(1 + eta^2) (i omega / omega_r)^p``: a fractional derivative, causal and passive, its
    loss factor eta at every frequency and its storage stiffness k at omega_r, growing as
    ``(omega / omega_r)^p`` (the Kramers-Kronig relations' price of a constant loss). The
    hysteretic modulus has the same loss and a constant storage stiffness, and is not causal. With
    eta = 0 both are k."""
    omega = np.asarray(omega, dtype=np.float64)
    stated = k * (1.0 + 1j * eta) * np.ones(omega.shape)
    if track.damping == "hysteretic":
        return stated
    power = 2.0 / np.pi * np.arctan(eta)
    return stated * (np.abs(omega) / (TWO_PI * track.damping_frequency)) ** power


def support_stiffness(omega, track):
    """Dynamic stiffness of one support (N/m): the pad in series with the sleeper mass on ballast::

        K_s = k_p* (k_b* - m_s omega^2) / (k_p* + k_b* - m_s omega^2)

(k* the complex moduli of pad and ballast, :func:`modulus`).

    ``omega`` (rad/s, any shape); ``track`` a :class:`~mdroll.track.Track`. Returns K_s (complex).
    """
    omega = np.asarray(omega, dtype=np.float64)
    pad = modulus(track.pad_stiffness, track.pad_loss, omega, track)
    below = modulus(track.ballast_stiffness, track.ballast_loss, omega, track) - track.sleeper_mass * omega**2
    return pad * below / (pad + below)


def foundation_stiffness(omega, track):
    """Foundation stiffness per length of the continuous model, ``K_f = K_s / sleeper_spacing``
    (N/m^2): the supports smeared along the rail."""
    return support_stiffness(omega, track) / track.sleeper_spacing


def wavenumbers(omega, track, K_f):
    """Wavenumbers k_j (rad/m, Im k_j >= 0) and residues A_j (1/N) of the Timoshenko rail on a
    foundation of stiffness per length K_f (N/m^2, complex, broadcast with omega): the two roots
    s_j = k_j^2 of P(s) (module docstring), with the rail's loss factor on E I and kappa G A
    (:func:`modulus`).
    Where a root is real (an undamped travelling wave), k_j = -sqrt(s_j): the wave
    exp(i (omega t - |k_j| |x|)) that carries energy away from the force.

    Returns ``(k, A)``, each of shape ``omega.shape + (2,)``.
    """
    omega = np.asarray(omega, dtype=np.float64)
    EI = modulus(track.rail_EI, track.rail_loss, omega, track)
    m_w2 = track.rail_mass * omega**2 - K_f
    rot = track.rail_rotary_inertia * omega**2
    if np.isinf(track.rail_shear_stiffness):
        s = np.sqrt(m_w2 / EI)
        roots = np.stack([s, -s], axis=-1)
        residues = np.stack([1.0 / (EI * 2 * s), -1.0 / (EI * 2 * s)], axis=-1)
    else:
        GA = modulus(track.rail_shear_stiffness, track.rail_loss, omega, track)
        a = GA * EI
        b = -(GA * rot + EI * m_w2)
        c = -m_w2 * (GA - rot)
        disc = np.sqrt(b * b - 4 * a * c + 0j)
        disc = np.where((np.conj(b) * disc).real >= 0, disc, -disc)  # no cancellation in b + disc
        q = -0.5 * (b + disc)
        roots = np.stack([q / a, c / q], axis=-1)
        d_of = EI[..., None] * roots + (GA - rot)[..., None]
        residues = d_of / (a[..., None] * (roots - roots[..., ::-1]))
    k = np.sqrt(roots + 0j)
    flip = (k.imag < 0) | ((k.imag == 0) & (k.real > 0))
    return np.where(flip, -k, k), residues


def green(x, omega, track, K_f):
    """Displacement at x (m) per unit force at 0 (m/N) of the rail on a foundation K_f (N/m^2):
    ``G(x) = (i / 2) sum_j A_j exp(i k_j |x|) / k_j`` (:func:`wavenumbers`). ``x`` broadcasts
    with ``omega``. ``G(0)`` is the point receptance."""
    k, A = wavenumbers(omega, track, K_f)
    x = np.abs(np.asarray(x, dtype=np.float64))[..., None]
    return 0.5j * np.sum(A * np.exp(1j * k * x) / k, axis=-1)


def continuous_receptance(f, track, x=0.0):
    """Receptance of the continuously supported rail (m/N) at frequencies ``f`` (Hz): the
    displacement at distance ``x`` (m) from a unit harmonic force, :func:`green` with
    :func:`foundation_stiffness`."""
    omega = TWO_PI * np.asarray(f, dtype=np.float64)
    return green(x, omega, track, foundation_stiffness(omega, track))


def continuous_decay_rate(f, track):
    """Decay rate (dB/m) of the continuously supported rail: ``DB_PER_NEPER * min_j Im k_j``, the
    attenuation of its least attenuated wave (:func:`wavenumbers`). ``f`` in Hz."""
    omega = TWO_PI * np.asarray(f, dtype=np.float64)
    k, _ = wavenumbers(omega, track, foundation_stiffness(omega, track))
    return DB_PER_NEPER * np.min(k.imag, axis=-1)


def cut_on_frequencies(track):
    """Frequencies (Hz) where the continuous track's k = 0 wave cuts on, ``rho A omega^2 = K_f``:
    the eigenfrequencies of rail (mass per length m_r) and sleeper (m_s / d) on pad (k_p / d) and
    ballast (k_b / d), undamped, in ascending order; without a sleeper mass the one frequency of
    the rail on pad and ballast in series."""
    d = track.sleeper_spacing
    m_r, k_p, k_b = track.rail_mass, track.pad_stiffness / d, track.ballast_stiffness / d
    if track.sleeper_mass == 0:
        return np.array([np.sqrt(k_p * k_b / (k_p + k_b) / m_r) / TWO_PI])
    m_s = track.sleeper_mass / d
    mass = np.diag([m_r, m_s])
    stiff = np.array([[k_p, -k_p], [-k_p, k_p + k_b]])
    eig = np.linalg.eigvals(np.linalg.solve(mass, stiff))
    return np.sort(np.sqrt(eig.real)) / TWO_PI
