"""Closed forms of the linear (small-roughness) contact filter in 1/3-octave wavelength bands.

To first order in the roughness, a contact held at a fixed approach answers a perturbation h(x, y)
of the surface with the force ``dF = integral h p_1 dA``, p_1 the flat-punch pressure of its contact
per unit indentation (total k, the contact stiffness). For a Hertz ellipse of semi-axes a_x (along
the track) and a_y, ``p_1 ~ (1 - x^2/a_x^2 - y^2/a_y^2)^(-1/2)`` and its Fourier transform is
``k sinc(sqrt((q_x a_x)^2 + (q_y a_y)^2))`` (the circle's ``2 pi sin(q a) / q`` of the inverse square
root, stretched), sinc(x) = sin(x)/x. The force PSD along the track is then

    C_F(q_x) = k^2 integral dq_y C_2D(q_x, q_y) T(q_x, q_y)

with the transfer T of the model:

* ``"3d"``: ``sinc^2(sqrt((q_x a_x)^2 + (q_y a_y)^2))``, the 3-D contact;
* ``"corrected"``: ``sinc^2(q_x a_x) sinc^2(q_y a_y)``, the corrected MDR (uniform line weight of
  half-length a_x on the surface averaged uniformly across ``|y| <= a_y``);
* ``"line"``: ``sinc^2(q_x a)``, the MDR on a measured line (eq 39 with C_1D = C_p), a its radius;
* ``"dprs"``: ``(2 J1(rho) / rho)^2``, ``rho = sqrt((q_x a_x)^2 + (q_y a_y)^2)``, the distributed
  point-reacting springs on Hertz's ellipse (:func:`mdroll.bem.dprs.transfer`: the roughness
  averaged uniformly over the patch), its k the bed's own stiffness.

The contact filter of a band b is the force's band power over ``k^2`` times the band power of the
profile roughness ``C_p(q_x) = integral dq_y C_2D`` (what a trolley measures):
``A(b) = 10 lg( integral_b C_F dq_x / (k^2 integral_b C_p dq_x) )`` (dB). For a corrugation
(C_2D concentrated on q_y = 0) every model reduces to its own transfer at q_y = 0 (``sinc^2(q_x a_x)``
for the first three), band-averaged.

Spectra: the self-affine ``C_2D ~ q_e^(-2H-2)``, ``q_e = sqrt(q_x^2 + (q_y / gamma)^2)``, on
``q_min <= q_e <= q_max`` (:func:`mdroll.bem.surfaces.areal_psd`); the level cancels in A.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import integrate

from ...bem.dprs import transfer as dprs_transfer
from ...bem.surfaces import areal_psd
from ...roughness.bands import wavelength_band_edges_q

#: Transfers of :func:`transfer` (module docstring).
MODELS = ("3d", "corrected", "line", "dprs")
#: Quadrature points per band along the track and across it.
POINTS_X, POINTS_Y = 32, 2001
#: The integral across the track stops at q_y = LATERAL_TOP / a_y (or 8 q_x): the spectrum and the
#: transfer have both decayed there.
LATERAL_TOP = 120.0


def _sinc2(x):
    x = np.asarray(x, dtype=np.float64)
    safe = np.where(x == 0.0, 1.0, x)
    return np.where(x == 0.0, 1.0, (np.sin(safe) / safe) ** 2)


def transfer(model: str, qx, qy, semi_x: float, semi_y: float, radius_line: float | None = None):
    """The transfer T(q_x, q_y) of ``model`` (module docstring); ``radius_line`` the contact
    radius of the "line" model (default a_x). Dimensionless."""
    if model == "3d":
        return _sinc2(np.sqrt((qx * semi_x) ** 2 + (qy * semi_y) ** 2))
    if model == "corrected":
        return _sinc2(qx * semi_x) * _sinc2(qy * semi_y)
    if model == "line":
        return _sinc2(qx * (semi_x if radius_line is None else radius_line)) * np.ones_like(qy)
    if model == "dprs":
        return dprs_transfer(qx, qy, semi_x, semi_y)
    raise ValueError(f"model {model!r} is not one of {MODELS}")


def _lateral_grid(qx: np.ndarray, semi_y: float, q_top: float) -> np.ndarray:
    """q_y >= 0 points (one row per q_x) for the integral across: fine near 0 (the spectrum's scale
    q_x) and resolving the transfer's oscillation (period pi / a_y) up to ``q_top``."""
    qx = qx[:, None]
    near = qx * np.linspace(0.0, 4.0, POINTS_Y // 4)[None, :]
    top = np.maximum(q_top, 8.0 * qx)
    far = 4.0 * qx + (top - 4.0 * qx) * np.linspace(0.0, 1.0, POINTS_Y)[None, 1:]
    return np.concatenate([near, far], axis=1)


def contact_filter(model: str, bands, semi_x: float, semi_y: float, H: float, *, q_min: float = 0.0,
                   q_max: float = math.inf, anisotropy: float = 1.0, corrugation: bool = False,
                   radius_line: float | None = None) -> np.ndarray:
    """A (dB) of ``model`` in the wavelength bands ``bands`` (band numbers, centre 10^(n/10) mm)
    for the self-affine roughness (H, q_min, q_max rad/m, ``anisotropy`` gamma), or for a
    corrugation of that profile spectrum (``corrugation``). NaN for a band without roughness."""
    q_lo, q_hi = wavelength_band_edges_q(bands)
    out = np.full(q_lo.size, np.nan)
    for i, (lo, hi) in enumerate(zip(q_lo, q_hi)):
        qx = np.linspace(lo, hi, POINTS_X)
        if corrugation:  # the profile's power law; its level cancels
            rough = areal_psd(qx, 0.0, H, q_min, q_max) * qx
            force = rough * transfer(model, qx, 0.0, semi_x, semi_y, radius_line)
        else:
            qy = _lateral_grid(qx, semi_y, LATERAL_TOP / semi_y)
            c2d = areal_psd(qx[:, None], qy, H, q_min, q_max, anisotropy)
            rough = 2.0 * integrate.trapezoid(c2d, qy, axis=1)
            force = 2.0 * integrate.trapezoid(c2d * transfer(model, qx[:, None], qy, semi_x, semi_y, radius_line),
                                              qy, axis=1)
        total = integrate.trapezoid(rough, qx)
        if total > 0:
            out[i] = 10.0 * math.log10(integrate.trapezoid(force, qx) / total)
    return out
