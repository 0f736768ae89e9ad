"""The linear wheel/rail interaction in the frequency domain (the TWINS chain; Remington 1987;
Thompson 2009, ch. 5): contact force, wheel and rail velocities from a roughness spectrum.

A roughness of wavenumber q passes the wheel at f = v q / (2 pi), omega = v q. The contact is the
linearized Hertz/MDR spring k_c = 2 E* a (:func:`mdroll.physics.contact_stiffness`) with the MDR
contact filter of eq 39: a mode of amplitude r drives the blocked contact with the force
``k_c sinc(q a) r`` (``E* W(q) = k_c sinc(q a)``, :func:`mdroll.physics.contact_window_transform`).
With wheel, rail and contact in series::

    F = sinc(q a) r / (alpha_W + alpha_R + alpha_C),   alpha_C = 1 / k_c,
    v_W = i omega alpha_W F,   v_R = i omega alpha_R F

(signs as Thompson 2009: alpha_W of a mass is -1 / (m omega^2)). On spectra: C_F = |H|^2 C_r with
H = sinc(q a) / (alpha_W + alpha_R + alpha_C); velocities likewise. Everything is vectorized.
"""

from __future__ import annotations

import numpy as np

from mdroll.physics import TWO_PI, contact_window_transform


def contact_filter(q, a):
    """MDR contact filter of eq 39 on amplitudes: ``sinc(q a) = sin(q a) / (q a)`` (1 at q = 0),
    ``E* W(q) / k_c``. ``q`` (rad/m), ``a`` contact radius (m). Dimensionless."""
    return contact_window_transform(q, a) / (2.0 * a)


def linear_chain(f, roughness_psd, alpha_wheel, alpha_rail, k_contact, a, v):
    """Spectra of the linear chain at frequencies ``f`` (Hz) for a roughness spectrum given at
    the same points (``roughness_psd``, any PSD convention, e.g. two-sided per rad/m in m^3).

    ``alpha_wheel``, ``alpha_rail``: receptances at f (m/N, complex); ``k_contact`` k_c (N/m);
    ``a`` contact radius (m); ``v`` speed (m/s). Returns a dict of arrays in the roughness PSD's
    convention: ``force`` (N^2 per m^2 of roughness PSD unit), ``wheel_velocity``,
    ``rail_velocity`` ((m/s)^2 likewise), ``blocked_force`` (rigid wheel and rail: eq 39's
    k_c^2 sinc^2 C_r) and ``transfer`` H (N/m, complex)."""
    f = np.asarray(f, dtype=np.float64)
    omega = TWO_PI * f
    q = omega / v
    filt = contact_filter(q, a)
    transfer = filt / (alpha_wheel + alpha_rail + 1.0 / k_contact)
    c_r = np.asarray(roughness_psd, dtype=np.float64)
    return {
        "force": np.abs(transfer) ** 2 * c_r,
        "wheel_velocity": np.abs(omega * alpha_wheel * transfer) ** 2 * c_r,
        "rail_velocity": np.abs(omega * alpha_rail * transfer) ** 2 * c_r,
        "blocked_force": (k_contact * filt) ** 2 * c_r,
        "transfer": transfer,
    }


def chain_for_params(params, f, alpha_wheel, alpha_rail):
    """:func:`linear_chain` with a :class:`mdroll.Params`' contact (k_c, a at the static load
    F_N), speed v0 and MDR-line roughness PSD C_1D(q) (two-sided, m^3 per rad/m; eq 33)."""
    q = TWO_PI * np.asarray(f, dtype=np.float64) / params.v0
    return linear_chain(f, params.psd(q), alpha_wheel, alpha_rail, params.k_contact, params.a, params.v0)
