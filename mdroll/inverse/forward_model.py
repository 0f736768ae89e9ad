"""The forward model of an averaged spectrum: what the inverse fit compares the data with.

Expected two-sided PSD per rad/s at omega (rad/s), q = omega / v0 (rad/m)::

    C_F(q)     = lambda A (2 E* / q)^2 q^(-2H-1) <sin^2(q a)> w(q)                 (eq 40, linear part)
               + 4 c^2 <cos^2(q a)> C_{h^2}(q) (1 - w(q)),   c = E* R / (4 a)    (eq 48, low band closed form)
    <sin^2(q a)> = (1 - cos(2 q a) exp(-2 q^2 s_a^2)) / 2,  <cos^2> = 1 - <sin^2>
    C_F(omega) = C_F(q) / v0                                                     (section 6)
    accel:       C_A(omega) = T(omega) C_F(omega),
                 T = w~^4 / ((k_c - m w~^2)^2 + (2 zeta sqrt(k_c m) w~)^2),   k_c = 2 E* a   (section 5.1)
    on a known track: the blocked force times |1 + k_c (alpha_W + alpha_R)|^-2, the acceleration
                 omega^4 |alpha_W|^2 times that (:mod:`mdroll.inverse.track_model`)
    observed:    S(omega) = C(omega) + leak / w~^2 + noise,  then the Hann stencil [1/6, 2/3, 1/6]
                 over neighbouring bins when the series was windowed (section 6).

* lambda A follows from h0 by eq 50: on the line's grid 2 pi k / L when L is known (mdroll
  spectra; the discrete normalization with which the lines are generated), else in the
  continuum ``lambda A = H h0^2 / (q_min^(-2H) - q_max^(-2H))`` (q_max -> infinity: eq 50's limit).
* ``s_a`` (``a_jitter``): the contact radius is a only on average; its edges move with the
  roughness under them (by about h R / (2 a), eq 47). Averaging sin^2(q a) over a Gaussian a of
  standard deviation s_a fills the zeros of eq 40 more and more towards high q, as simulated
  spectra show; s_a = 0 is eq 40 itself. The quadratic term is used below q_min only, where it
  is the whole fluctuation (physics.md section 7): above, eq 49's edge term overshoots.
* ``w(q)`` is 1 inside [q_min, q_max] and 0 outside, except in the bin that holds a cutoff, where
  it is the fraction of the bin [q_k - dq, q_k] beyond it (dq the data's bin width), so the
  likelihood is continuous in q_min and q_max; the discrete eq 50 uses the same fractions on the
  line's grid.
* ``C_{h^2}(q) = 2 integral C_1D(q') C_1D(q - q') dq'`` (Isserlis' factor 2; physics.md section 7,
  eq 48) by FFT convolution (:func:`square_line_psd`).
* ``w~ = 2 sin(omega dt / 2) / dt`` when the sample interval dt is known (the simulation's
  semi-implicit Euler wheel: |G|^2 of mdroll.kernels.moments.ResponseBin is exactly T at
  zeta = 0), else omega. ``zeta`` is a damping ratio (measured wheels are damped; in a simulated
  spectrum it absorbs the finite resolution of the undamped resonance).
* ``leak / w~^2``: the periodogram of a series that is not periodic (the open boundary without a
  window) has a tail ~ jump^2 / q^2; ``noise``: an additive white floor of the measurement. Both
  in the PSD's own units (times (rad/s)^2 for leak).

Identifiability (v0 known; it maps omega to q, and with it unknown only a / v0 and q_min v0 are
identified):

============================  =================================================  =============================
data and band                 identified                                         degenerate (only the product)
============================  =================================================  =============================
force, high band              H, q_min, a, q_max (if in band), E*^2 lambda A      E* and h0: fix one
force, + low band             + R^2 lambda A / a^2 (the ratio of the two terms)   E*, h0, R: one relation left
accel, high band only         H, q_min, a, (E*/m)^2 lambda A                      E*, m, h0: fix two
accel, + resonance            + omega_0^2 = 2 E* a / m, so E*/m and h0            E* and m: fix m (or E*)
accel, + resonance, m known   H, q_min, a, E*, h0, F_N R = 4 a^3 E* / 3           F_N and R: fix one
============================  =================================================  =============================

``E`` and ``nu`` enter only through E* (eq 1-2). A known ``F_N`` makes a a function of R and E*
(eq 14-15) instead of a parameter.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.signal
import scipy.special

from ..errors import ParameterError
from .. import physics
from .track_model import KnownTrack

#: Every parameter the model can fit: (unit, transform, lower, upper). "log": fitted as its
#: natural logarithm (positive); "linear": as is.
PARAMETERS = {
    "H": ("-", "linear", 0.02, 0.98),
    "q_min": ("rad/m", "log", 1e-3, 1e9),
    "q_max": ("rad/m", "log", 1e-3, 1e10),
    "a": ("m", "log", 1e-6, 1.0),
    "E_star": ("Pa", "log", 1e6, 1e14),
    "h0": ("m", "log", 1e-12, 1e-2),
    "R": ("m", "log", 1e-4, 1e3),
    "m": ("kg", "log", 1e-3, 1e7),
    "a_jitter": ("m", "log", 1e-9, 1e-2),
    "low_scale": ("-", "log", 1e-3, 1e3),
    "zeta": ("-", "log", 1e-7, 1.0),
    "noise": ("PSD", "log", 1e-300, 1e300),
    "leak": ("PSD (rad/s)^2", "log", 1e-300, 1e300),
}
#: Inputs that can only be known, never fitted: they set model parameters (see :func:`resolve_known`).
KNOWN_ONLY = ("v0", "E", "nu", "F_N")
#: Values of the nuisance parameters when they are neither fitted nor given.
NUISANCE_DEFAULTS = {"a_jitter": 0.0, "low_scale": 1.0, "zeta": 0.0, "noise": 0.0, "leak": 0.0, "q_max": math.inf}

_SQUARE_GRID_PER_QMIN = 32
_SQUARE_GRID_EXTENT = 8.0


def resolve_known(known: dict) -> dict:
    """Model parameters from what is known: E and nu give E_star (eq 1-2); v0 stays as is. F_N is
    kept: with R and E* it sets a (eq 14-15, :func:`contact_radius_from_load`) in the fit.
    Unknown names and non-positive values end with a ParameterError."""
    allowed = set(PARAMETERS) | set(KNOWN_ONLY)
    out = {}
    for name, value in known.items():
        if name not in allowed:
            raise ParameterError(f"unknown parameter {name!r} in known; valid ones are: {', '.join(sorted(allowed))}")
        try:
            value = float(value)
        except (TypeError, ValueError):
            raise ParameterError(f"known {name} = {value!r} is not a number") from None
        if not math.isfinite(value) and not (name == "q_max" and value == math.inf):
            raise ParameterError(f"known {name} = {value!r} is not allowed: it must be finite")
        if name == "nu":
            if not -1.0 < value < 0.5:
                raise ParameterError(f"known nu = {value!r} is not allowed: Poisson's ratio must lie in (-1, 0.5)")
        elif name == "H":
            if not 0.0 < value < 1.0:
                raise ParameterError(f"known H = {value!r} is not allowed: it must lie in (0, 1)")
        elif value < 0 or (value == 0 and name not in NUISANCE_DEFAULTS):
            raise ParameterError(f"known {name} = {value!r} is not allowed: it must be positive")
        out[name] = value
    if "E" in out or "nu" in out:
        if "E_star" in out:
            raise ParameterError("give either E_star or E (with nu), not both")
        out["E_star"] = float(physics.effective_modulus(out.pop("E", 210e9), out.pop("nu", 0.3)))
    return out


def contact_radius_from_load(F_N, E_star, R):
    """a from the load, eq 14-15: ``a = sqrt(d0 R)``, ``d0 = (3 F_N / (4 E* sqrt(R)))^(2/3)`` (m)."""
    return physics.contact_radius(physics.hertz_indentation(F_N, E_star, R), R)


def load_times_radius(a, E_star):
    """F_N R = (4/3) E* a^3 (N m): what the high band and the resonance fix of load and radius (eq 14-15)."""
    return 4.0 / 3.0 * E_star * a**3


def band_weights(q, low, high, dq):
    """w(q): 1 for low <= q <= high, 0 beyond, and in the bin of width ``dq`` ending at q that holds
    a cutoff the fraction of it inside (continuous in the cutoffs; see the module docstring)."""
    q = np.asarray(q, dtype=np.float64)
    above = np.clip((q - low) / dq + 1.0, 0.0, 1.0)
    below = np.clip((high - q) / dq + 1.0, 0.0, 1.0) if math.isfinite(high) else 1.0
    return above * below


def lambda_A(h0, H, q_min, q_max, line_length=None):
    """The prefactor lambda A of eq 50 (m^(2-2H)) that gives the line the RMS height h0 (m), in the
    form the fit needs (continuous in the cutoffs, O(1) per call). With ``line_length``
    L (m): the discrete sum ``sum_k w_k q_k^(-2H-1)`` on the grid q_k = k dq, dq = 2 pi / L, with
    the fractional end weights w_k of :func:`band_weights` (so it equals
    :func:`mdroll.physics.lambda_A_discrete` when the cutoffs lie on the grid), summed in closed
    form by Hurwitz zeta functions ``sum_{k >= n} k^-s = zeta(s, n)``; without: the continuum
    ``H h0^2 / (q_min^(-2H) - q_max^(-2H))``."""
    if line_length is None:
        tail = 0.0 if not math.isfinite(q_max) else q_max ** (-2.0 * H)
        return H * h0**2 / (q_min ** (-2.0 * H) - tail)
    dq = physics.TWO_PI / line_length
    s = 2.0 * H + 1.0
    low = q_min / dq
    first = max(1, math.ceil(low - 1e-9))
    total = float(scipy.special.zeta(s, first))
    if first - 1 >= 1 and first - low < 1.0:  # the bin below, partly inside
        total += (first - low) * (first - 1) ** -s
    if math.isfinite(q_max):
        high = q_max / dq
        last = math.floor(high + 1e-9)
        total -= float(scipy.special.zeta(s, last + 1))
        total += (high - last) * (last + 1) ** -s if high - last > 1e-9 else 0.0
    total *= dq**-s
    return h0**2 / (2.0 * dq * total) if total > 0 else math.inf


def square_line_psd(q, lam_A, H, q_min, q_max):
    """``C_{h^2}(q) = 2 integral C_1D(q') C_1D(q - q') dq'`` (m^5), the PSD of h^2 for a Gaussian
    line (Isserlis; physics.md section 7), for 0 <= q <= 8 q_min (0 beyond): an FFT convolution
    of C_1D on a grid of q_min / 32 up to 8 q_min (and q_max); the pairs it leaves out weigh
    about 8^-(4H+1) (1 % at H = 0.3)."""
    q = np.asarray(q, dtype=np.float64)
    step = q_min / _SQUARE_GRID_PER_QMIN
    top = min(q_max, _SQUARE_GRID_EXTENT * q_min)
    grid = np.arange(-math.ceil(top / step), math.ceil(top / step) + 1) * step
    line = physics.roughness_psd(grid, lam_A, H, q_min, top)
    full = 2.0 * step * scipy.signal.fftconvolve(line, line, mode="same")
    positive = grid >= 0
    return np.interp(q, grid[positive], full[positive], right=0.0)


@dataclass(frozen=True)
class Setting:
    """What the model needs to know about the data beyond the parameters."""

    quantity: str
    v0: float
    dt: float | None = None
    window: bool = False
    line_length: float | None = None
    bin_width: float | None = None  # d omega of the data's bins (rad/s), for the cutoff fractions
    correction: "Correction | None" = None  # the simulated discrepancy r(q), see :class:`Correction`
    known_track: "KnownTrack | None" = None  # the track under the contact (:mod:`mdroll.inverse.track_model`)


@dataclass(frozen=True)
class Correction:
    """The simulated discrepancy of the closed-form model: ``r(q) = exp(g(log q))``, g piecewise
    linear between ``knots`` (log q, q in rad/m) with the values ``log_ratio`` and constant beyond
    them. It multiplies the series' own spectrum (the leakage included; not the noise floor of a
    measurement; before the window's stencil), so that ``S = r(q) C(omega)``: the mean of spectra
    simulated with the exact MDR force (the contact's non-linearity included) over eq 40 and eq
    48, smoothed over octaves (:mod:`mdroll.inverse.correction`). ``covariance``: that of ``log_ratio``; ``gain``:
    per free parameter of the fit, the factor 1 / (1 - rho) by which the iteration to the fixed
    point amplifies a shift of the estimate (rho its measured contraction), applied to the
    standard errors."""

    knots: tuple
    log_ratio: tuple
    covariance: tuple = ()
    gain: tuple = ()

    def factor(self, q) -> np.ndarray:
        """r(q) (dimensionless) at the wavenumbers ``q`` (rad/m)."""
        with np.errstate(divide="ignore"):
            return np.exp(np.interp(np.log(q), self.knots, self.log_ratio))

    def shifted(self, k: int, step: float) -> "Correction":
        """The same with ``log_ratio[k]`` moved by ``step`` (for derivatives)."""
        values = list(self.log_ratio)
        values[k] += step
        return Correction(self.knots, tuple(values), self.covariance, self.gain)


def setting_for(spectrum, v0: float, correction: Correction | None = None) -> Setting:
    """The :class:`Setting` of a :class:`~mdroll.inverse.observed.Spectrum` rolled at ``v0`` (m/s):
    its quantity, dt, window, line length and bin width (the first step of a uniform grid, else
    the smallest)."""
    omega = spectrum.omega
    step = float(np.diff(omega).min()) if omega.size > 1 else None
    width = float(omega[1] - omega[0]) if spectrum.uniform else step
    return Setting(spectrum.quantity, v0, spectrum.dt, spectrum.window, spectrum.line_length, bin_width=width,
                   correction=correction, known_track=spectrum.known_track)


def effective_frequency(omega, dt):
    """w~ = 2 sin(omega dt / 2) / dt (rad/s): the frequency the semi-implicit Euler oscillator
    of step dt responds to as the continuous one does to omega (section 5.1); omega without dt."""
    omega = np.asarray(omega, dtype=np.float64)
    return omega if dt is None else 2.0 * np.sin(0.5 * omega * dt) / dt


def wheel_transfer(omega, k_contact, m, zeta, dt=None):
    """|A/F|^2 ((m/s^2)/N)^2 of the wheel on the linearized contact spring (section 5.1) with the
    damping ratio zeta: ``w~^4 / ((k_c - m w~^2)^2 + (2 zeta sqrt(k_c m) w~)^2)``; at zeta = 0 and
    without dt it is :func:`mdroll.physics.acceleration_transfer`."""
    w = effective_frequency(omega, dt)
    with np.errstate(divide="ignore"):
        return w**4 / ((k_contact - m * w**2) ** 2 + (2.0 * zeta * math.sqrt(k_contact * m) * w) ** 2)


def expected_psd(omega, p: dict, setting: Setting) -> np.ndarray:
    """The model S(omega) of the module docstring (two-sided per rad/s) at ``omega`` (rad/s), for
    parameters ``p`` (SI; keys of :data:`PARAMETERS`). With ``setting.window`` ``omega`` must be a
    run of consecutive bins of the data's grid; the stencil's end bins use the model one bin out."""
    omega = np.asarray(omega, dtype=np.float64)
    if setting.window:
        step = setting.bin_width
        padded = np.concatenate([[omega[0] - step], omega, [omega[-1] + step]])
        raw = _unwindowed(np.abs(padded), p, setting)
        return raw[1:-1] * (2.0 / 3.0) + (raw[:-2] + raw[2:]) / 6.0
    return _unwindowed(omega, p, setting)


def _unwindowed(omega, p: dict, setting: Setting) -> np.ndarray:
    v0 = setting.v0
    q = omega / v0
    lam = lambda_A(p["h0"], p["H"], p["q_min"], p["q_max"], setting.line_length)
    dq = setting.bin_width / v0 if setting.bin_width else 0.0
    weights = band_weights(q, p["q_min"], p["q_max"], dq) if dq else physics.in_roughness_band(q, p["q_min"], p["q_max"])
    # sin^2(q a) and cos^2(q a) of eq 40 and eq 48 averaged over a Gaussian jitter of a (see the docstring)
    fill = np.cos(2.0 * q * p["a"]) * np.exp(-2.0 * (q * p["a_jitter"]) ** 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        linear = np.where(q > 0, (2.0 * p["E_star"] / q) ** 2 * lam * q ** (-2.0 * p["H"] - 1.0) * 0.5 * (1.0 - fill), 0.0)
    c = physics.edge_coefficient(p["E_star"], p["R"], p["a"])
    below = weights < 1.0  # the quadratic term is used below q_min only
    quadratic = np.zeros_like(q)
    quadratic[below] = (p["low_scale"] * 4.0 * c * c * 0.5 * (1.0 + fill[below])
                        * square_line_psd(q[below], lam, p["H"], p["q_min"], p["q_max"]) * (1.0 - weights[below]))
    psd = (weights * linear + quadratic) / v0
    w = effective_frequency(omega, setting.dt)
    if setting.known_track is not None:
        psd = psd * setting.known_track.gain(omega, p, setting.quantity, setting.dt)
    elif setting.quantity == "accel":
        psd = psd * wheel_transfer(omega, physics.contact_stiffness(p["E_star"], p["a"]), p["m"], p["zeta"], setting.dt)
    with np.errstate(divide="ignore"):
        psd = psd + np.where(w > 0, p["leak"] / np.where(w > 0, w, 1.0) ** 2, 0.0)
    if setting.correction is not None:  # the series' own spectrum, not the measurement's noise floor
        psd = psd * setting.correction.factor(q)
    return psd + p["noise"]


def derived(p: dict) -> dict:
    """Derived quantities of a full parameter set: lambda A (continuum, eq 50), the level
    E*^2 lambda A, k_c = 2 E* a, omega_0 = sqrt(k_c / m), F_N R = 4 a^3 E* / 3 and F_N."""
    k_c = physics.contact_stiffness(p["E_star"], p["a"])
    return {
        "k_c": float(k_c),
        "omega_0": float(physics.resonance_frequency(k_c, p["m"])),
        "F_N_R": float(load_times_radius(p["a"], p["E_star"])),
        "F_N": float(load_times_radius(p["a"], p["E_star"]) / p["R"]),
        "level": float(p["E_star"] ** 2 * lambda_A(p["h0"], p["H"], p["q_min"], p["q_max"])),
    }


def check_free(free, quantity: str, known: dict) -> list[str]:
    """The free parameters, checked: known names, not also known, and no combination the table of
    the module docstring calls degenerate without saying so (a ParameterError names it)."""
    free = list(dict.fromkeys(free))
    for name in free:
        if name not in PARAMETERS:
            raise ParameterError(f"unknown free parameter {name!r}; valid ones are: {', '.join(PARAMETERS)}")
        if name in known:
            raise ParameterError(f"{name} is both known and free; drop one")
    if "a" in free and "F_N" in known:
        raise ParameterError("a follows from the known F_N with R and E* (eq 14-15); drop a from free or F_N from known")
    if quantity == "force" and {"E_star", "h0"} <= set(free):
        raise ParameterError("E_star and h0 are degenerate in a force spectrum (only E*^2 lambda A is identified): "
                             "fix one of them")
    if quantity == "accel" and {"E_star", "m"} <= set(free):
        raise ParameterError("E_star and m are degenerate in an acceleration spectrum (the resonance gives 2 E* a / m):"
                             " fix one of them")
    if quantity == "accel" and {"E_star", "h0"} <= set(free) and "m" not in known and "m" not in free:
        raise ParameterError("E_star and h0 need the wheel mass m: give it as known (the resonance gives E*/m)")
    return free


def default_free(quantity: str, known: dict, leaky: bool = False) -> list[str]:
    """The default free set: H, q_min, a and h0 (unless known or fixed by F_N), E_star when the data
    can tell it (acceleration with m known), a_jitter, and leak for a ``leaky`` spectrum (a
    simulated one without the window: the open series, and the decoupled wheel's response from
    rest even on a periodic line, are not periodic). (zeta only matters with the resonance in
    the band, which the default band leaves out: free it when you include it.)"""
    free = [n for n in ("H", "q_min", "a", "h0") if n not in known]
    if "a" in free and "F_N" in known:
        free.remove("a")
    if "E_star" not in known:
        if quantity == "accel" and "m" in known:
            free.append("E_star")
        elif quantity == "force" and "h0" in free:
            raise ParameterError("a force spectrum gives only E*^2 lambda A: give E (or E_star) or h0 as known")
        elif quantity == "accel":
            raise ParameterError("an acceleration spectrum gives E* only with the wheel mass: give m (or E/E_star) "
                                 "as known")
    if "a_jitter" not in known:
        free.append("a_jitter")
    if leaky and "leak" not in known:
        free.append("leak")
    return free
