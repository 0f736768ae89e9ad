"""The MDR contact filter in 1/3-octave bands, beside the CNOSSOS-EU contact filter A3.

Eq 39 for any spectrum (:func:`mdroll.physics.force_psd_linear`): the linear force of the MDR
line is ``C_F(q) = k_c^2 sinc^2(q a) C_1D(q)`` with ``k_c = 2 E* a``, ``sinc(x) = sin(x) / x``. Referred
to the profile roughness (the rail assumption, :mod:`mdroll.roughness.kinds`: ``C_1D = C_p``)
and normalized by the quasi-static stiffness k_c, the contact filter of band b is

    A_MDR(b) = 10 lg( integral_b sinc^2(q a) C_p(q) dq / integral_b C_p(q) dq )   (dB)

so that the force level is ``L_F = L_r + A_MDR + 20 lg(k_c r0 / F0)`` (r0 = 1 um, F0 = 1 N). With
C_p constant across a band (the band-level PSD of :class:`~mdroll.roughness.tabulated.BandLevels`)
the integral is closed: ``integral sin^2(x)/x^2 dx = Si(2x) - sin^2(x)/x``. CNOSSOS-EU adds its
A3 to the roughness level the same way (effective roughness), so the two compare band by band.
"""

from __future__ import annotations

import numpy as np
from scipy import integrate, special

from .. import physics
from ..params import Params
from . import tables
from .bands import band_numbers, wavelength_band_edges_q


def _sinc2_antiderivative(x):
    """``integral_0^x sin^2(t)/t^2 dt = Si(2x) - sin^2(x)/x`` (x > 0)."""
    x = np.asarray(x, dtype=np.float64)
    return special.sici(2.0 * x)[0] - np.sin(x) ** 2 / x


def mdr_contact_filter(n, a: float, spectrum=None, points: int = 2001) -> np.ndarray:
    """A_MDR (dB) of wavelength bands n (centre 10^(n/10) mm) for contact radius a (m): the band
    average of ``sinc^2(q a)`` weighted by the profile PSD of ``spectrum`` (a
    :class:`~mdroll.roughness.kinds.RoughnessSpectrum`; None: constant across each band, closed
    form), module docstring."""
    q_lo, q_hi = wavelength_band_edges_q(n)
    if spectrum is None:
        mean = (_sinc2_antiderivative(q_hi * a) - _sinc2_antiderivative(q_lo * a)) / ((q_hi - q_lo) * a)
        return 10.0 * np.log10(mean)
    out = np.empty(q_lo.size)
    for i, (lo, hi) in enumerate(zip(q_lo, q_hi)):
        q = np.linspace(lo, hi, points)
        weight = spectrum.profile_psd(q)
        sinc2 = (physics.contact_window_transform(q, a) / (2.0 * a)) ** 2
        out[i] = 10.0 * np.log10(integrate.trapezoid(sinc2 * weight, q) / integrate.trapezoid(weight, q))
    return out


def cnossos_comparison(base: Params | None = None) -> dict:
    """The MDR contact filter beside CNOSSOS-EU A3 for A3's five (wheel load, wheel diameter) cases.

    For each case the MDR contact radius is eq 15 with ``F_N`` the wheel load and ``R`` half the
    diameter (the MDR's sphere of the wheel radius, materials of ``base``). Returns
    ``{"wavelength_mm": nominal centres, "cases": [{"load_N", "diameter_m", "a_m", "A3_dB",
    "MDR_dB", "difference_dB" (MDR - A3)}, ...]}``, every list per band, longest wavelength first."""
    base = Params() if base is None else base
    wavelengths, a3 = tables.cnossos_a3()
    n = band_numbers(wavelengths)
    cases = []
    for (load, diameter), a3_db in a3.items():
        a = float(physics.contact_radius(physics.hertz_indentation(load, base.E_star, diameter / 2.0), diameter / 2.0))
        mdr = mdr_contact_filter(n, a)
        cases.append({"load_N": load, "diameter_m": diameter, "a_m": a, "A3_dB": a3_db.tolist(),
                      "MDR_dB": mdr.tolist(), "difference_dB": (mdr - a3_db).tolist()})
    return {"wavelength_mm": wavelengths.tolist(), "cases": cases, "source": tables.A3_SOURCE}
