"""The roughness spectrum interface and the conversions between its kinds.

Bottom layer (numpy and scipy only, beside :mod:`mdroll.physics`): the line generator
(:mod:`mdroll.ensemble.lines`) reads the spectra through this interface; the concrete spectra are
in :mod:`.analytic` and :mod:`.tabulated`, their values on a line's grid in :mod:`.line_grid`.

Conventions (physics.md section 3). A one-dimensional spectrum C(q) (m^3) is two-sided: a
line's mean square is ``<h^2> = integral over q of both signs C(q) dq ~ sum_k (2 pi / L) C(q_k)``.
An areal spectrum C_2D(q) (m^4) of an isotropic surface is normalized as
``<h^2> = integral d^2q C_2D(|q|) = 2 pi integral_0^inf q C_2D(q) dq``. Wavenumbers in rad/m.

Every spectrum says which kind it is:

* ``"mdr"``: the spectrum of the MDR line itself (eq 33: what the generator needs);
* ``"profile"``: of a line scan along the rail, what a roughness trolley measures (EN 15610);
* ``"areal"``: the isotropic areal spectrum C_2D.

and converts explicitly (:meth:`RoughnessSpectrum.mdr_psd`, :meth:`RoughnessSpectrum.profile_psd`):

* areal -> MDR line, Geike's rule (eq 8) ``C_1D(q) = lambda |q| C_2D(|q|)``; with the RMS
  normalization of eq 50 (the line has the surface's RMS) ``lambda = pi`` for every H
  (:data:`GEIKE_LAMBDA`: ``2 integral lambda q C_2D dq = (lambda / pi) <h^2>``);
* areal -> profile, integration across the track:
  ``C_p(q_x) = integral dq_y C_2D(sqrt(q_x^2 + q_y^2)) = 2 integral_0^inf C_2D(q_x cosh t) q_x cosh t dt``;
* for a power law ``C_2D = A q^(-2H-2)`` the two are in the constant ratio
  ``C_1D / C_p = lambda Gamma(H + 1) / (sqrt(pi) Gamma(H + 1/2))`` (:func:`mdr_to_profile_ratio`);
* profile -> MDR line for rail roughness (:data:`RAIL_ASSUMPTION`): a corrugation constant across
  the contact width, ``h(x, y) = h(x)``. The linear force of a 3D Hertz contact of radius a on a
  small perturbation is the perturbation weighted by the flat-punch pressure per unit
  indentation, ``p_1(r) = E* / (pi sqrt(a^2 - r^2))`` (integral 2 E* a = k_c). Integrating p_1 over
  y across the circle gives ``E*`` for every |x| < a, so the force is ``E* integral_{x-a}^{x+a} h dx``,
  exactly the MDR line's linear force (physics.md section 6) with ``h_MDR = h``: the MDR line
  spectrum equals the profile spectrum, ``C_1D = C_p``, and eq 39 applies to the measured
  profile directly.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from scipy import integrate, special

from ..errors import ParameterError
from ..params import SPECTRUM_KINDS

#: Geike's factor lambda of C_1D = lambda q C_2D fixed by the RMS normalization (eq 8, eq 50).
GEIKE_LAMBDA = math.pi
#: The assumption that carries a profile (line-scan) spectrum to the MDR line.
RAIL_ASSUMPTION = "corrugation"
#: Reference roughness of a roughness level, L_r = 10 lg(r^2 / r0^2) (m): 1 um.
ROUGHNESS_REFERENCE = 1e-6


def check_kind(kind) -> str:
    """``kind`` if it names a spectrum kind ("mdr", "profile", "areal"), else a ParameterError."""
    if kind not in SPECTRUM_KINDS:
        raise ParameterError(f"kind = {kind!r} is not allowed: choose one of {list(SPECTRUM_KINDS)}")
    return kind


def check_spectrum(value):
    """``value`` if it is a :class:`RoughnessSpectrum` or None (the argument ``roughness`` of the
    API's ensembles and lines), else a ParameterError naming it."""
    if value is not None and not isinstance(value, RoughnessSpectrum):
        raise ParameterError(f"roughness = {value!r} is not allowed: give a spectrum of mdroll.roughness (e.g. "
                             "mdroll.roughness.iso3095()) or None; the model names go in Params(roughness=...)")
    return value


class RoughnessSpectrum:
    """A roughness spectrum C(q) of a given kind.

    Subclasses implement :meth:`psd` (the spectrum in its own kind: m^3 for "mdr" and "profile",
    m^4 for "areal") and set ``kind``, ``absolute`` (whether the level is physical; a shape
    alone can only be used with the RMS normalization) and ``support`` (q_lo, q_hi), the
    wavenumbers (rad/m) outside which C is zero.
    """

    kind: str = "mdr"
    absolute: bool = False
    support: tuple[float, float] = (0.0, math.inf)

    def psd(self, q) -> np.ndarray:
        raise NotImplementedError

    def describe(self) -> dict:
        """A JSON-ready description (type and parameters)."""
        raise NotImplementedError

    # ------------------------------------------------------------------ conversions
    def mdr_psd(self, q, geike_lambda: float = GEIKE_LAMBDA) -> np.ndarray:
        """C_1D(q) of the MDR line (m^3, two-sided): the spectrum itself for "mdr"; the profile
        spectrum under the rail assumption (corrugation across the contact width, module
        docstring) for "profile"; Geike's rule ``lambda |q| C_2D(|q|)`` (eq 8) for "areal"."""
        q = np.abs(np.asarray(q, dtype=np.float64))
        if self.kind == "areal":
            return geike_lambda * q * self.psd(q)
        return self.psd(q)

    def profile_psd(self, q, geike_lambda: float = GEIKE_LAMBDA) -> np.ndarray:
        """C_p(q) of a line scan along the rail (m^3, two-sided): the spectrum itself for
        "profile" and, by the rail assumption, for "mdr"; for "areal" the integral across the
        track ``2 integral_0^inf C_2D(q cosh t) q cosh t dt`` (:func:`scipy.integrate.quad_vec`)."""
        q = np.abs(np.asarray(q, dtype=np.float64))
        if self.kind != "areal":
            return self.psd(q)
        return areal_to_profile(self.psd, q, self.support[1])

    def grid_mdr_psd(self, q, dq: float) -> np.ndarray:
        """C_1D on the line's grid q = k dq (rad/m) for generation: :meth:`mdr_psd` at the grid
        points (band spectra distribute each band's power over its bins instead)."""
        return self.mdr_psd(q)

    def mean_square(self, q_lo: float = 0.0, q_hi: float = math.inf, points: int = 20001) -> float:
        """Mean square height of the MDR line from the band q_lo..q_hi (m^2):
        ``2 integral C_1D dq`` on a log grid (trapezoid; C_1D zero outside its support)."""
        lo = max(q_lo, self.support[0], 1e-3)
        hi = min(q_hi, self.support[1], 1e8)
        if not hi > lo:
            return 0.0
        q = np.geomspace(lo, hi, points)
        return 2.0 * float(integrate.trapezoid(self.mdr_psd(q), q))


def areal_to_profile(areal_psd: Callable, q, q_top: float = math.inf) -> np.ndarray:
    """Profile PSD of an isotropic surface (m^3): ``C_p(q) = 2 integral_0^T C_2D(q cosh t) q cosh t dt``
    with ``T = arccosh(q_top / q)`` (C_2D is zero above q_top, rad/m) or 30 (C_2D decaying).

    ``areal_psd``: C_2D(q) (m^4, vectorized over q in rad/m); ``q`` (rad/m, > 0)."""
    q = np.atleast_1d(np.abs(np.asarray(q, dtype=np.float64)))
    out = np.zeros_like(q)
    inside = q < q_top
    if not np.any(inside):
        return out
    qs = q[inside]
    top = np.arccosh(q_top / qs) if math.isfinite(q_top) else np.full_like(qs, 30.0)

    def integrand(s):  # s in [0, 1] maps to t = s * top per wavenumber
        t = s * top
        return 2.0 * areal_psd(qs * np.cosh(t)) * qs * np.cosh(t) * top

    out[inside] = integrate.quad_vec(integrand, 0.0, 1.0, epsrel=1e-8, limit=400)[0]
    return out


def mdr_to_profile_ratio(H: float, geike_lambda: float = GEIKE_LAMBDA) -> float:
    """For an isotropic power law ``C_2D = A q^(-2H-2)``: ``C_1D / C_p = lambda Gamma(H+1) /
    (sqrt(pi) Gamma(H+1/2))`` away from the cut-offs (``C_p = A q^(-2H-1) sqrt(pi)
    Gamma(H+1/2) / Gamma(H+1)``, the integral across the track). Dimensionless."""
    return geike_lambda * special.gamma(H + 1.0) / (math.sqrt(math.pi) * special.gamma(H + 0.5))
