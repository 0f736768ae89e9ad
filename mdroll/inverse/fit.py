"""The Whittle fit of an averaged spectrum: estimates, Fisher intervals, profiles, goodness of fit.

Likelihood. A periodogram bin of a Gaussian series is its expected value S times chi^2_2 / 2;
the mean of K independent passes is ``S chi^2_nu / nu`` with nu = 2K degrees of freedom, a Gamma
variable of shape kappa = nu / 2. Averaging B neighbouring bins (``bin=B``) gives nu = 2 K B
when the bins are independent (the model is averaged over the same bins). The negative
log-likelihood used, up to terms free of the parameters, is

    -log L(theta) = kappa * sum_j [ log S_j(theta) + P_j / S_j(theta) ]          (Whittle)

over the bins j in the band; the estimate does not depend on kappa. Positive parameters are
fitted as their logarithms (H as is), bounded (:data:`mdroll.inverse.forward_model.PARAMETERS`), by
scipy.optimize L-BFGS-B from data-driven starting values (a power law for H, the modulation
frequency of the flattened spectrum for a, a scan for q_min, the peak for the resonance).

Intervals. The expected Fisher information of the Whittle likelihood is
``I = kappa * J^T J`` with ``J_jk = d log S_j / d theta_k`` (central differences). Simulated
and measured spectra are rarely exactly chi-square: fixed-amplitude lines scatter less, a
window correlates neighbouring bins (Hann: the variance of a sum over bins is 1.94x the
independent one), and the model is not exact. So the covariance reported is the quasi-likelihood
one, ``phi * tau * I^-1``, with the Pearson dispersion ``phi = sum z_j^2 / (n - p)`` of the
standardized residuals ``z_j = sqrt(kappa) (P_j / S_j - 1)`` and ``tau`` their long-run variance
factor (:func:`long_run_factor`: batch means over blocks of 1, 2, 4, ... bins while 16 blocks
fit, the largest), which covers the correlation of neighbouring bins and a smooth misfit of the
model over many bins alike; the raw ``I^-1`` intervals are kept as ``ci95_fisher``. A cutoff
(q_min, q_max) is located to within a bin of width dq at best: its variance gets the uniform
``(dq / q)^2 / 12`` (in log scale) added. Intervals are symmetric in the fitted (log) scale.
Profiles: for each free parameter, the others re-fitted on a grid of +-4 calibrated standard errors, as the deviance
difference divided by phi tau; a profile that stays below 3.84 on a side is an open interval
(a degeneracy or a weakly identified direction).

Goodness of fit: the Gamma deviance ``D = 2 kappa sum (P/S - log(P/S) - 1)`` against chi^2 with
n - p degrees of freedom, phi and tau, and a Kolmogorov-Smirnov test of P/S against the Gamma law.

Fill check (:func:`_fill_check`): where the noise floor and the contact-radius jitter are both
free they trade, and h0 and E* follow them beyond what the local intervals say; the fit is
repeated with a_jitter held at eq 47's edge displacement and the shift d widens the covariance,
``cov + d d^T``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
import scipy.ndimage
import scipy.optimize
import scipy.stats

from ..ensemble.spec import run_specs
from ..files import jsonable
from ..params import ParameterError
from ..physics import TWO_PI, edge_displacement
from .forward_model import (NUISANCE_DEFAULTS, PARAMETERS, Correction, check_free, contact_radius_from_load, default_free,
                    derived, expected_psd, lambda_A, resolve_known, setting_for)
from .observed import Spectrum

Z95 = scipy.stats.norm.ppf(0.975)
CHI2_95 = scipy.stats.chi2.ppf(0.95, 1)
#: Block sizes (bins) of the batch-means estimate of the residuals' long-run variance: powers of
#: 2 while at least 16 blocks fit.
BLOCK_SIZES = tuple(2**i for i in range(24))
MIN_BINS_PER_PARAMETER = 5
MIN_BINS = 10
#: Default top of the band of a simulated spectrum, as a fraction of its Nyquist frequency pi/dt
#: (25 q_min at the defaults, where physics.md finds eq 40 within 1 % of the direct sum): above
#: it the contact's non-linearity and the springs' discretization change the spectrum's slope
#: (data / model from 0.96 at q_min to 1.05 at 100 q_min and 0.97 at 200 q_min, H = 0.4, L =
#: 0.5 m, 30 passes), which biased H by +0.05 with the band to 0.5 pi/dt, +0.010 to 0.1 and
#: +0.0015 to 0.05.
SIMULATED_BAND_TOP = 0.05
#: The default band of an acceleration spectrum starts at this multiple of its resonance: the
#: periodogram of a finite record of an (almost) undamped resonance is not |A/F|^2 times the
#: force's near omega_0 (the record's end states cancel part of the peak), while above it the
#: response's shape ((1 - omega_0^2 / omega^2)^-2: x1.78 at 2 omega_0) still fixes E* with m.
RESONANCE_MARGIN = 2.0
#: When the fill check runs (:func:`fit`'s ``fill_check``): "auto" where the noise floor and the
#: contact-radius jitter are both free (the two nuisances that fill the zeros of sin^2(q a)),
#: "on" wherever the jitter is free, "off" never.
FILL_CHECKS = ("auto", "on", "off")
#: The fill check's refits hold a_jitter at eq 47's h R / (2 a) of their own estimate: at most
#: this many, until it changes by less than :data:`FILL_CHECK_TOLERANCE` (relative).
FILL_CHECK_ITERATIONS = 5
FILL_CHECK_TOLERANCE = 1e-3
#: The model discrepancy of a closed-form fit of a table (:func:`fit`'s ``discrepancy``): the
#: ratio r(q) of the exact MDR spectrum to the closed form, which a table cannot simulate, taken
#: as unknown, ``log r(q) = c0 + c1 log2(q / q_mid) +- 0`` with c0 and c1 independent, of mean 0 and
#: standard deviations (level, tilt per octave) = the root mean squares of the least-squares
#: intercept and slope of log r that the simulated correction measured in the full grid (K >= 100:
#: 0.027 and 0.018 per knot, 252 round trips; docs/inverse.md, "The model discrepancy of a table").
DISCREPANCY = (0.03, 0.02)
_HUGE = 1e30


@dataclass
class FitResult:
    """The outcome of :func:`fit`. Values in SI units (see :data:`~mdroll.inverse.forward_model.PARAMETERS`).

    ``estimates``: every model parameter (free ones estimated, the rest as fixed); ``ci95``,
    ``stderr``: the free ones' calibrated 95 % intervals and standard errors; ``ci95_fisher``: the
    uncalibrated ones; ``derived``: derived quantities with delta-method intervals; ``gof``:
    goodness of fit; ``profiles``: ``{name: {"values": [...], "delta": [...], "ci95": [lo, hi]}}``.
    """

    free: list
    estimates: dict
    known: dict
    stderr: dict
    ci95: dict
    ci95_fisher: dict
    covariance: np.ndarray
    correlation: np.ndarray
    derived: dict
    gof: dict
    band: tuple
    kappa: float
    passes: int
    passes_assumed: bool
    success: bool
    message: str
    omega: np.ndarray
    data: np.ndarray
    model: np.ndarray
    quantity: str
    profiles: dict = field(default_factory=dict)
    truth: dict | None = None
    bootstrap: dict | None = None
    correction: dict | None = None
    correction_used: Correction | None = None
    fill_check: dict | None = None
    discrepancy: dict | None = None

    def to_dict(self) -> dict:
        """A JSON-ready dict (arrays as lists; the band's data and model included)."""
        out = {
            "free": self.free, "estimates": self.estimates, "known": self.known, "stderr": self.stderr,
            "ci95": {k: list(v) for k, v in self.ci95.items()},
            "ci95_fisher": {k: list(v) for k, v in self.ci95_fisher.items()},
            "correlation": self.correlation.tolist(), "covariance_fitted_scale": self.covariance.tolist(),
            "fitted_scale": {n: PARAMETERS[n][1] for n in self.free},
            "derived": self.derived, "gof": self.gof, "band_rad_s": list(self.band), "kappa": self.kappa,
            "passes": self.passes, "passes_assumed": self.passes_assumed, "success": self.success,
            "message": self.message, "quantity": self.quantity,
            "profiles": self.profiles, "truth": self.truth, "bootstrap": self.bootstrap, "correction": self.correction,
            "fill_check": self.fill_check, "discrepancy": self.discrepancy,
            "convention": "two-sided PSD per rad/s on omega (rad/s)",
            "omega": self.omega.tolist(), "data": self.data.tolist(), "model": self.model.tolist(),
        }
        return jsonable(out)

    def table(self) -> str:
        """The estimates as a text table: value, 95 % interval (calibrated), truth when known."""
        lines = [f"{'parameter':<10} {'estimate':>12} {'95% low':>12} {'95% high':>12} {'unit':<14}"
                 + (f" {'truth':>12} {'error':>9}" if self.truth else "")]
        for name in self.free:
            lo, hi = self.ci95[name]
            row = f"{name:<10} {self.estimates[name]:>12.6g} {lo:>12.6g} {hi:>12.6g} {PARAMETERS[name][0]:<14}"
            if self.truth and name in self.truth:
                row += f" {self.truth[name]:>12.6g} {_error(name, self.estimates[name], self.truth[name]):>9}"
            lines.append(row)
        for name, item in self.derived.items():
            lo, hi = item["ci95"]
            row = f"{name:<10} {item['value']:>12.6g} {lo:>12.6g} {hi:>12.6g} {item['unit']:<14}"
            if self.truth and name in self.truth:
                row += f" {self.truth[name]:>12.6g} {_error(name, item['value'], self.truth[name]):>9}"
            lines.append(row)
        g = self.gof
        lines.append(f"bins {g['bins']}, deviance/dof {g['deviance_per_dof']:.3g}, dispersion phi {g['phi']:.3g}, "
                     f"long-run factor tau {g['tau']:.3g}, KS p {g['ks_p']:.3g}, K = {self.passes}"
                     + (" (assumed)" if self.passes_assumed else ""))
        c = self.correction
        if c and "ratio" in c:
            lines.append(f"simulated correction r = {min(c['ratio']):.3g} .. {max(c['ratio']):.3g} over the band, "
                         f"{len(c['iterates'])} iterations" + ("" if c["converged"] else " (not converged)"))
        elif c:
            lines.append(f"simulated correction skipped: {c.get('skipped', 'not converged')}")
        d = self.discrepancy
        if d:
            widened = ", ".join(f"{n} x{w:.2g}" for n, w in d["widening"].items() if w >= 1.1) or "none by 10 %"
            lines.append(f"model discrepancy (not simulated): log r = 0 +- {d['level']:g} +- {d['tilt']:g} per octave; "
                         f"intervals widened: {widened}")
        f = self.fill_check
        if f:
            widened = ", ".join(f"{n} x{w:.2g}" for n, w in f["widening"].items() if w >= 1.1) or "none by 10 %"
            lines.append(f"fill check: a_jitter {f['a_jitter_fitted']:.3g} m fitted, {f['a_jitter_edge']:.3g} m by eq 47; "
                         f"intervals widened by the shift to it: {widened}")
        return "\n".join(lines)


def _error(name: str, value: float, truth: float) -> str:
    return f"{value - truth:+.3f}" if name == "H" else f"{100 * (value / truth - 1):+.2f}%"


class _Problem:
    """The data of the band, the free and fixed parameters and the objective in fitted scale."""

    def __init__(self, spectrum: Spectrum, known: dict, free, band, passes, bin_size: int,
                 correction: Correction | None = None):
        self.spectrum = spectrum
        known = resolve_known(known or {})
        v0 = known.pop("v0", None)
        if v0 is None:
            v0 = spectrum.v0
        elif spectrum.v0 is not None and not math.isclose(v0, spectrum.v0, rel_tol=1e-9):
            raise ParameterError(f"known v0 = {v0!r} m/s contradicts the spectrum's own v0 = {spectrum.v0!r} m/s")
        if v0 is None:
            raise ParameterError("v0 is not known: the rolling speed maps frequency to wavenumber; give it as known "
                                 "(e.g. --known v0=10)")
        self.v0 = v0
        self.load = known.pop("F_N", None)
        self.known = {**known, "v0": v0, **({"F_N": self.load} if self.load is not None else {})}
        leaky = spectrum.dt is not None and not spectrum.window
        self.free = check_free(default_free(spectrum.quantity, self.known, leaky) if free is None else free,
                               spectrum.quantity, self.known)
        if not self.free:
            raise ParameterError("no free parameter: name at least one (free=[...] or --free)")
        fixed = dict(NUISANCE_DEFAULTS)
        if spectrum.dt is not None:  # a simulated spectrum: its line reaches the Nyquist wavenumber pi/dx
            fixed["q_max"] = math.pi / (v0 * spectrum.dt)
        if spectrum.quantity == "force":
            fixed.update(m=1.0, zeta=0.0)  # the force does not see the wheel
        fixed.update({k: v for k, v in known.items() if k in PARAMETERS})
        needed = [n for n in PARAMETERS if n not in self.free and n not in fixed
                  and not (n == "a" and self.load is not None)]
        if needed:
            raise ParameterError(f"{', '.join(needed)} neither known nor free: give each as known (e.g. --known "
                                 f"{needed[0]}=...) or fit it (--free)")
        self.fixed = {k: v for k, v in fixed.items() if k not in self.free}
        self.band = _check_band(band, spectrum)
        inside = (spectrum.omega >= self.band[0]) & (spectrum.omega <= self.band[1])
        count = int(inside.sum())
        if count == 0:
            raise ParameterError(f"band {self.band[0]:.6g}..{self.band[1]:.6g} rad/s holds no bin of the spectrum, "
                                 f"which covers {spectrum.omega[0]:.6g}..{spectrum.omega[-1]:.6g} rad/s")
        if isinstance(bin_size, bool) or not isinstance(bin_size, (int, np.integer)) or bin_size < 1:
            raise ParameterError(f"bin = {bin_size!r} is not allowed: it must be a positive integer")
        usable = (count // bin_size) * bin_size
        needed_bins = max(MIN_BINS, MIN_BINS_PER_PARAMETER * len(self.free))
        if usable // bin_size < needed_bins:
            raise ParameterError(f"band {self.band[0]:.6g}..{self.band[1]:.6g} rad/s holds {count} bins "
                                 f"({usable // bin_size} after binning by {bin_size}); at least {needed_bins} are needed "
                                 f"for {len(self.free)} free parameters")
        index = np.flatnonzero(inside)[:usable]
        self.omega_all = spectrum.omega[index]
        self.bin_size = bin_size
        self.omega = self.omega_all.reshape(-1, bin_size).mean(axis=1)
        self.data = spectrum.psd[index].reshape(-1, bin_size).mean(axis=1)
        self.passes_assumed = passes is None and spectrum.passes is None
        self.passes = int(passes if passes is not None else (spectrum.passes or 1))
        self.kappa = self.passes * bin_size
        self.setting = setting_for(spectrum, v0, correction)
        positive = self.data > 0
        self.offset = float(np.mean(np.log(self.data[positive]))) + 1.0 if positive.any() else 0.0
        self.lower = np.array([_to_fitted(n, PARAMETERS[n][2]) for n in self.free])
        self.upper = np.array([_to_fitted(n, PARAMETERS[n][3]) for n in self.free])

    # ------------------------------------------------------------------ parameters
    def params(self, theta) -> dict:
        p = dict(self.fixed)
        p.update({n: _from_fitted(n, t) for n, t in zip(self.free, theta)})
        if self.load is not None:
            p["a"] = float(contact_radius_from_load(self.load, p["E_star"], p["R"]))
        return p

    def theta(self, p: dict) -> np.ndarray:
        return np.array([_to_fitted(n, p[n]) for n in self.free])

    def model(self, p: dict) -> np.ndarray:
        with np.errstate(over="ignore", invalid="ignore"):  # trial points of the searches may overflow it
            values = expected_psd(self.omega_all, p, self.setting)  # (E*, q_min far out): the objective refuses
        return values.reshape(-1, self.bin_size).mean(axis=1)

    def objective(self, theta) -> float:
        """(log S + P/S) averaged over the bins, less a constant: -log L / (kappa n)."""
        S = self.model(self.params(theta))
        if not np.all(np.isfinite(S)) or np.any(S <= 0):
            return _HUGE
        return float(np.mean(np.log(S) + self.data / S)) - self.offset

    def log_model_jacobian(self, theta) -> np.ndarray:
        """d log S_j / d theta_k (n, p) by central differences."""
        columns = []
        for k in range(len(theta)):
            h = 1e-5 * max(1.0, abs(theta[k]))
            up, down = theta.copy(), theta.copy()
            up[k] += h
            down[k] -= h
            columns.append((np.log(self.model(self.params(up))) - np.log(self.model(self.params(down)))) / (2 * h))
        return np.column_stack(columns)


def _to_fitted(name: str, value: float) -> float:
    return math.log(value) if PARAMETERS[name][1] == "log" else float(value)


def _from_fitted(name: str, value: float) -> float:
    return math.exp(min(value, 700.0)) if PARAMETERS[name][1] == "log" else float(value)


def _check_band(band, spectrum: Spectrum) -> tuple[float, float]:
    if band is None:
        top = spectrum.omega[-1] if spectrum.dt is None else min(spectrum.omega[-1], SIMULATED_BAND_TOP * math.pi / spectrum.dt)
        bottom = spectrum.omega[0]
        resonance = find_resonance(spectrum.omega, spectrum.psd) if spectrum.quantity == "accel" else None
        if resonance is not None:
            bottom = max(bottom, RESONANCE_MARGIN * resonance)
        return float(bottom), float(top)
    try:
        lo, hi = (float(b) for b in band)
    except (TypeError, ValueError):
        raise ParameterError(f"band = {band!r} is not allowed: give (omega_lo, omega_hi) in rad/s") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and 0 <= lo < hi):
        raise ParameterError(f"band = ({lo!r}, {hi!r}) rad/s is not allowed: it needs 0 <= omega_lo < omega_hi, finite")
    return lo, hi


def fit(spectrum: Spectrum, known: dict | None = None, free=None, band=None, passes: int | None = None,
        bin: int = 1, start: dict | None = None, profile: bool = True, profile_points: int = 9,
        correction=None, correction_passes: int | None = None, device: str = "auto", runner=None,
        fill_check: str = "auto", discrepancy: float | None = None) -> FitResult:
    """Fit the forward model (:mod:`mdroll.inverse.forward_model`) to ``spectrum`` by the Whittle likelihood.

    Parameters
    ----------
    spectrum : :class:`~mdroll.inverse.observed.Spectrum` (see :func:`~mdroll.inverse.read_spectrum`).
    known : ``{name: value}`` in SI units: any of :data:`~mdroll.inverse.forward_model.PARAMETERS` and
        ``v0`` (m/s), ``E`` (Pa) with ``nu``, ``F_N`` (N; a then follows from R and E*, eq 14-15).
    free : names to fit (default :func:`~mdroll.inverse.forward_model.default_free`).
    band : (omega_lo, omega_hi) in rad/s (default: the whole spectrum).
    passes : K, the number of averaged passes (default the spectrum's, else 1, marked assumed).
    bin : average this many neighbouring bins first (nu = 2 K bin).
    start : starting values for some free parameters (SI), instead of the data-driven ones.
    profile : compute the profile likelihood of each free parameter (``profile_points`` each).
    correction : "simulated" (the default for a spectrum that carries its simulation's settings,
        an mdroll one): the closed form times the ratio r(q) that simulations at the estimate
        measure (:mod:`mdroll.inverse.correction`), iterated, with r's uncertainty in the
        intervals; "none" (the default for a table): the closed form alone; or a
        :class:`~mdroll.inverse.forward_model.Correction` to hold fixed (e.g. ``result.correction_used``).
    correction_passes : passes K_c of each correction ensemble (default
        :func:`mdroll.inverse.correction.default_passes`: 32, or more to roll 80 m). device,
        runner : where those ensembles run (:func:`mdroll.run_specs`).
    fill_check : "auto" (default), "on" or "off" (:data:`FILL_CHECKS`): refit with a_jitter held at
        the edge displacement of eq 47, ``h0 R / (2 a)`` of the refit's own estimate, and add the
        shift of every free parameter to its variance (:func:`_fill_check`); "auto" where the noise
        floor and a_jitter are both free, "on" wherever a_jitter is free.
    discrepancy : (level, tilt) >= 0, the closed form's unknown discrepancy with correction "none":
        ``log r(q) = c0 + c1 log2(q / q_mid)`` (q_mid the band's geometric middle, in rad/m) with
        c0 and c1 of mean 0 and standard deviations level and tilt (per octave), at knots an
        octave apart over the band, added to the covariance by the delta method
        (:func:`_correction_covariance`) and recorded in ``result.discrepancy``; None (default):
        :data:`DISCREPANCY` for a table (a spectrum without the simulation's settings, which the
        simulated correction needs), none otherwise; 0: none.

    Returns a :class:`FitResult`. Bad input ends with a ParameterError naming it.
    """
    if fill_check not in FILL_CHECKS:
        raise ParameterError(f"fill_check = {fill_check!r} is not allowed: use one of {', '.join(map(repr, FILL_CHECKS))}")
    mode = _correction_mode(correction, spectrum)
    simulate = mode == "simulated"
    sigma = _discrepancy_sigma(discrepancy, mode, spectrum)
    if simulate and not {"L", "dx", "nu"} <= set(spectrum.simulation):
        raise ParameterError("correction = 'simulated' needs the simulation's L, dx and nu (an mdroll spectrum, or a "
                             "table given simulation={'L': ..., 'dx': ..., 'nu': ...}); use correction='none' otherwise")
    problem = _Problem(spectrum, known, free, band, passes, bin,
                       correction if isinstance(correction, Correction) else None)
    if sigma:
        from .correction import knots

        positions = knots((problem.omega[0] / problem.v0, problem.omega[-1] / problem.v0))
        octaves = (np.asarray(positions) - np.mean(positions)) / math.log(2.0)
        basis = np.column_stack([np.ones_like(octaves), octaves])  # knot values = basis @ (c0, c1)
        prior = Correction(positions, (0.0,) * len(positions),
                           tuple(map(tuple, (basis @ np.diag(np.square(sigma)) @ basis.T).tolist())))
        problem.setting = dataclasses.replace(problem.setting, correction=prior)
    p0 = _starting_values(problem, start or {})
    theta, best = _estimate(problem, np.clip(problem.theta(p0), problem.lower, problem.upper))
    if simulate:
        from . import correction as simulated

        k_c = correction_passes
        if k_c is not None and (isinstance(k_c, bool) or not isinstance(k_c, (int, np.integer)) or k_c < 1):
            raise ParameterError(f"correction_passes = {k_c!r} is not allowed: it must be a positive integer")
        closed_form = _result(problem, theta, best, spectrum, profile=False, profile_points=profile_points)
        result = simulated.iterate([spectrum], [closed_form], refit=lambda jobs: [refit(job, bin) for job in jobs],
                                   simulate=lambda specs: run_specs(specs, device=device, runner=runner),
                                   passes=k_c)[0]
        if profile:
            final = result
            result = refit((spectrum, final, final.correction_used), bin, profile=True, profile_points=profile_points)
            result.correction = {**(result.correction or {}), **final.correction}
    else:
        result = _result(problem, theta, best, spectrum, profile, profile_points)
        if sigma:
            result = _discrepancy_record(result, sigma)
    return _fill_check(spectrum, result, bin, fill_check)


def _discrepancy_sigma(discrepancy, mode: str, spectrum: Spectrum) -> tuple | None:
    """The (level, tilt) of :func:`fit`'s ``discrepancy``, checked, or None for none: the default's
    rule; an explicit one only with the closed form alone."""
    if discrepancy is None:
        return DISCREPANCY if mode == "none" and not spectrum.simulation else None
    if isinstance(discrepancy, (int, float)) and not isinstance(discrepancy, bool) and discrepancy == 0:
        return None
    try:
        level, tilt = (float(v) for v in discrepancy)
    except (TypeError, ValueError):
        level = tilt = math.nan
    if not (0 <= level < 1 and 0 <= tilt < 1):
        raise ParameterError(f"discrepancy = {discrepancy!r} is not allowed: give (level, tilt per octave) of log r, "
                             "each in [0, 1), or 0 for none")
    if mode != "none":
        raise ParameterError(f"discrepancy = {discrepancy!r} applies to the closed form alone (correction='none'), "
                             f"not to correction = {mode!r}, which measures r")
    return (level, tilt) if level or tilt else None


def _discrepancy_record(result: FitResult, sigma: tuple) -> FitResult:
    """The fit with the discrepancy prior (r = 1, its covariance from ``sigma`` = (level, tilt),
    held as its correction) recorded as ``result.discrepancy`` instead of a correction: the knots
    (q, rad/m), level and tilt, the variance added per parameter (fitted scale), the widening of
    each interval and the intervals without it."""
    record = result.correction
    added = record["variance_fitted_scale"]
    without, widening = {}, {}
    for name in result.free:
        total = result.stderr[name] / (result.estimates[name] if PARAMETERS[name][1] == "log" else 1.0)
        local = math.sqrt(max(total**2 - added[name], 0.0))
        widening[name] = total / local if 0 < local < math.inf else 1.0
        theta = _to_fitted(name, result.estimates[name])
        without[name] = [_from_fitted(name, theta - Z95 * local), _from_fitted(name, theta + Z95 * local)]
    return dataclasses.replace(result, correction=None, discrepancy={
        "level": sigma[0], "tilt": sigma[1], "q_knots": record["q_knots"], "variance_fitted_scale": added,
        "widening": widening, "ci95_without": without})


def refit(job, bin: int = 1, profile: bool = False, profile_points: int = 9) -> FitResult:
    """Fit ``spectrum`` again like ``previous`` (its known, free, band and passes; started at its
    estimates) with the fixed ``correction`` (None: the closed form alone): ``job = (spectrum,
    previous, correction)`` (a top-level function: worker processes run it). Without the fill check:
    :func:`fit` runs it once, on its final result."""
    spectrum, previous, correction = job
    return fit(spectrum, known=previous.known, free=previous.free, band=previous.band,
               passes=None if previous.passes_assumed else previous.passes, bin=bin,
               start={n: previous.estimates[n] for n in previous.free}, profile=profile,
               profile_points=profile_points, correction="none" if correction is None else correction,
               fill_check="off")


def _fill_check(spectrum: Spectrum, result: FitResult, bin: int, mode: str) -> FitResult:
    """The fill check (docs/inverse.md, "When the nuisances trade"): where it applies (``mode``,
    :data:`FILL_CHECKS`), refit with a_jitter held at the edge displacement of eq 47,
    ``s_a = h0 R / (2 a)`` of the refit's own estimate (iterated to that fixed point; the other
    parameters free, the correction held), and widen the covariance (fitted scale) by the shift d
    of the free parameters, ``cov + d d^T`` (a_jitter's own: from its fitted value to eq 47's).

    Why: a white noise floor fills the zeros of sin^2(q a) as the jitter does. Free together, they
    trade, and the high band's level, hence h0 and E*, follows them: h0 -12 %, E* +14 % at v0 =
    20 m/s (a_jitter 15 um fitted where eq 47 gives 24 um), outside intervals that a local
    expansion computes. Where the data separate them, the fitted jitter is eq 47's (23-26 um
    against 24.7 um at the defaults) and d is small against the standard errors."""
    applies = "a_jitter" in result.free and (mode == "on" or (mode == "auto" and "noise" in result.free))
    free = [n for n in result.free if n != "a_jitter"]
    if not applies or not free:
        return result
    tied, jitter = result, None
    # held: the correction's r, without its gain (one per free parameter of the original fit; the
    # held fits give estimates only)
    held = dataclasses.replace(result.correction_used, gain=()) if result.correction_used else "none"
    for _ in range(FILL_CHECK_ITERATIONS):
        p = tied.estimates
        previous, jitter = jitter, float(edge_displacement(p["h0"], p["R"], p["a"]))
        if previous is not None and abs(jitter / previous - 1.0) < FILL_CHECK_TOLERANCE:
            break
        tied = fit(spectrum, known={**result.known, "a_jitter": jitter}, free=free, band=result.band,
                   passes=None if result.passes_assumed else result.passes, bin=bin,
                   start={n: p[n] for n in free}, profile=False,
                   correction=held, fill_check="off")
    values = {**{n: tied.estimates[n] for n in free}, "a_jitter": jitter}
    shift = np.array([_to_fitted(n, values[n]) - _to_fitted(n, result.estimates[n]) for n in result.free])
    problem = _Problem(spectrum, result.known, result.free, result.band,
                       None if result.passes_assumed else result.passes, bin, result.correction_used)
    theta = problem.theta(result.estimates)
    cov = result.covariance + np.outer(shift, shift)
    sd = np.sqrt(np.abs(np.diag(cov)))
    before = dict(result.stderr)
    ci, stderr = _intervals(result.free, theta, result.estimates, sd)
    with np.errstate(invalid="ignore", divide="ignore"):
        correlation = cov / np.outer(sd, sd)
    record = {"rule": mode, "a_jitter_fitted": result.estimates["a_jitter"], "a_jitter_edge": jitter,
              "estimates_held": values, "shift_fitted_scale": dict(zip(result.free, shift.tolist())),
              "stderr_local": before, "ci95_local": {n: list(v) for n, v in result.ci95.items()},
              "widening": {n: stderr[n] / before[n] if 0 < before[n] < math.inf else 1.0 for n in result.free}}
    return dataclasses.replace(result, covariance=cov, correlation=correlation, stderr=stderr, ci95=ci,
                               derived=_derived(problem, theta, cov), fill_check=record)


def _intervals(free, theta, estimates: dict, sd) -> tuple[dict, dict]:
    """The 95 % intervals, symmetric in the fitted scale, and the standard errors (SI) of the free
    parameters from their standard deviations ``sd`` in the fitted scale; unbounded where sd is
    not finite (an unidentified parameter)."""
    ci, stderr = {}, {}
    for i, name in enumerate(free):
        if not np.isfinite(sd[i]):
            ci[name] = (0.0, math.inf) if PARAMETERS[name][1] == "log" else (-math.inf, math.inf)
            stderr[name] = math.inf
            continue
        ci[name] = (_from_fitted(name, theta[i] - Z95 * sd[i]), _from_fitted(name, theta[i] + Z95 * sd[i]))
        stderr[name] = sd[i] * (estimates[name] if PARAMETERS[name][1] == "log" else 1.0)
    return ci, stderr


def _result(problem: _Problem, theta, best, spectrum: Spectrum, profile: bool, profile_points: int) -> FitResult:
    """The FitResult at the estimate ``theta``: intervals, goodness of fit, profiles."""
    f_hat = problem.objective(theta)
    S = problem.model(problem.params(theta))
    n, k = problem.data.size, len(problem.free)
    kappa = problem.kappa

    z = math.sqrt(kappa) * (problem.data / S - 1.0)
    phi = float(np.sum(z * z) / max(n - k, 1))
    tau, block_taus = long_run_factor(z)
    scale = phi * tau

    jac = problem.log_model_jacobian(theta)
    information = kappa * jac.T @ jac
    raw_cov, unidentified = _inverse_information(information, problem.free)
    # r's part by the delta method, with I^-1 itself: the cutoffs' resolution below is a variance,
    # not information (added to I^-1 first, it made G's q_min row kappa J^T J_c times the bin's
    # variance: q_min's interval 12x too wide under a 0.02 per octave tilt)
    correction_cov = _correction_covariance(problem, theta, raw_cov, jac, unidentified)
    cov = scale * raw_cov
    for name in ("q_min", "q_max"):  # a cutoff is located to within a bin: its uniform variance
        if name in problem.free and name not in unidentified:
            i = problem.free.index(name)
            resolution = (problem.setting.bin_width / problem.v0 / _from_fitted(name, theta[i])) ** 2 / 12.0
            cov[i, i] += resolution
            raw_cov[i, i] += resolution
    cov = cov + correction_cov
    if problem.setting.correction is not None and problem.setting.correction.gain:
        gain = np.asarray(problem.setting.correction.gain)
        cov = cov * np.outer(gain, gain)
    sd = np.sqrt(np.abs(np.diag(cov)))
    sd_raw = np.sqrt(np.abs(np.diag(raw_cov)))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    estimates = problem.params(theta)
    ci, stderr = _intervals(problem.free, theta, estimates, sd)
    ci_raw = _intervals(problem.free, theta, estimates, np.where(np.isfinite(sd), sd_raw, math.inf))[0]

    positive = problem.data > 0
    ratio = problem.data[positive] / S[positive]
    deviance = float(2.0 * kappa * np.sum(ratio - np.log(ratio) - 1.0))
    dof = max(n - k, 1)
    gof = {"bins": n, "dof": dof, "deviance": deviance, "deviance_per_dof": deviance / dof,
           "deviance_p": float(scipy.stats.chi2.sf(deviance, dof)), "phi": phi, "tau": tau,
           "tau_by_block": block_taus,
           "ks_p": float(scipy.stats.kstest(problem.data / S, scipy.stats.gamma(kappa, scale=1.0 / kappa).cdf).pvalue),
           "nll_per_bin": f_hat, "unidentified": unidentified}

    result = FitResult(
        free=problem.free, estimates=estimates, known=problem.known, stderr=stderr, ci95=ci, ci95_fisher=ci_raw,
        covariance=cov, correlation=corr, derived=_derived(problem, theta, cov), gof=gof, band=problem.band,
        kappa=kappa, passes=problem.passes, passes_assumed=problem.passes_assumed, success=bool(best.success),
        message=str(best.message), omega=problem.omega, data=problem.data, model=S, quantity=spectrum.quantity,
        truth=_truth_of(spectrum), correction=_correction_record(problem, correction_cov),
        correction_used=problem.setting.correction,
    )
    if profile:
        result.profiles = _profiles(problem, theta, f_hat, sd, scale, profile_points)
        lower = min((min(v["delta"]) for v in result.profiles.values()), default=0.0)
        result.gof["profile_found_lower_minimum"] = bool(lower < -0.5)
    return result


def _estimate(problem: _Problem, theta0):
    """The maximum-likelihood estimate from ``theta0``: L-BFGS-B, the cutoff's scan, L-BFGS-B again
    (restarted: its first stop is often early, or on a bin's kink)."""
    best = _minimize(problem, theta0)
    best = _minimize(problem, _polish_cutoff(problem, best.x))
    return best.x, best


def _correction_mode(correction, spectrum: Spectrum) -> str:
    if correction is None:
        return "simulated" if spectrum.simulation else "none"
    if isinstance(correction, Correction):
        return "fixed"
    if correction not in ("simulated", "none"):
        raise ParameterError(f"correction = {correction!r} is not allowed: use 'simulated', 'none' or a Correction")
    return correction


def _correction_covariance(problem: _Problem, theta, raw_cov, jac, unidentified) -> np.ndarray:
    """What the correction's uncertainty adds to the covariance (fitted scale), by the delta
    method: ``G cov_c G^T`` with ``G = d theta_hat / d c = -I^-1 kappa J^T J_c``, J_c = d log S / d c
    (central differences); zero without a correction or for unidentified parameters."""
    correction = problem.setting.correction
    out = np.zeros_like(raw_cov)
    if correction is None or not correction.covariance:
        return out
    setting = problem.setting
    columns = []
    for k in range(len(correction.log_ratio)):
        logs = []
        for step in (1e-4, -1e-4):
            problem.setting = dataclasses.replace(setting, correction=correction.shifted(k, step))
            logs.append(np.log(problem.model(problem.params(theta))))
        columns.append((logs[0] - logs[1]) / 2e-4)
    problem.setting = setting
    keep = np.array([n not in unidentified for n in problem.free])
    gain = -raw_cov[np.ix_(keep, keep)] @ (problem.kappa * jac[:, keep].T @ np.column_stack(columns))
    out[np.ix_(keep, keep)] = gain @ np.asarray(correction.covariance) @ gain.T
    return out


def _correction_record(problem: _Problem, correction_cov) -> dict | None:
    """The correction for the record: r at its knots with standard errors and the variance it
    adds to each parameter (fitted scale)."""
    correction = problem.setting.correction
    if correction is None:
        return None
    q = np.exp(correction.knots)
    ratio = correction.factor(q)
    errors = np.sqrt(np.diag(np.asarray(correction.covariance))) if correction.covariance else np.zeros(q.size)
    return {"q_knots": q.tolist(), "ratio": ratio.tolist(), "log_ratio_stderr": errors.tolist(),
            "variance_fitted_scale": dict(zip(problem.free, np.diag(correction_cov).tolist())),
            "gain": dict(zip(problem.free, correction.gain))}


def long_run_factor(z, blocks=BLOCK_SIZES, least_blocks: int = 16):
    """How much more the sum of the residuals ``z`` varies than if they were independent: for each
    block size B (with at least ``least_blocks`` blocks) the batch-means estimate
    ``tau_B = B var(block means of z) / var(z)``; returns max_B tau_B (at least 0.25) and the dict
    of tau_B. Neighbouring-bin correlation (Hann: 1.94) shows at small B, a systematic misfit of
    the model over many bins at large B: either makes the information sum over bins overstate
    what the data know by that factor."""
    z = np.asarray(z, dtype=np.float64)
    variance = float(np.var(z)) or 1.0
    taus = {}
    for size in blocks:
        count = z.size // size
        if count < least_blocks:
            break
        means = z[: count * size].reshape(count, size).mean(axis=1)
        taus[size] = float(size * np.var(means) / variance)
    return max(0.25, max(taus.values(), default=1.0)), taus


def _polish_cutoff(problem: _Problem, theta):
    """q_min by a scan over +-3 bins in quarter bins, the other parameters held: the likelihood has
    a kink at every bin (the fractional bin weight of :func:`~mdroll.inverse.forward_model.band_weights`)."""
    if "q_min" not in problem.free:
        return theta
    i = problem.free.index("q_min")
    bin_q = problem.setting.bin_width / problem.v0
    centre = _from_fitted("q_min", theta[i])
    best, best_f = theta, problem.objective(theta)
    for q in centre + bin_q * np.arange(-3.0, 3.01, 0.25):
        if q <= 0:
            continue
        trial = theta.copy()
        trial[i] = _to_fitted("q_min", q)
        f = problem.objective(trial)
        if f < best_f:
            best, best_f = trial, f
    return best


def _inverse_information(information, names):
    """The inverse of the Fisher information, with the parameters that take part in a direction
    it does not constrain (an eigenvalue below 1e-10 of the largest: a degeneracy) marked
    unidentified and given infinite variance."""
    values, vectors = np.linalg.eigh(information)
    null = values <= 1e-10 * max(values.max(), 1e-300)
    inverse = (vectors[:, ~null] / values[~null]) @ vectors[:, ~null].T
    involved = np.any(np.abs(vectors[:, null]) > 0.1, axis=1) if null.any() else np.zeros(len(names), bool)
    inverse[involved, :] = np.nan
    inverse[:, involved] = np.nan
    inverse[involved, involved] = np.inf
    return inverse, [n for n, bad in zip(names, involved) if bad]


def _truth_of(spectrum: Spectrum) -> dict | None:
    if not spectrum.truth:
        return None
    truth = dict(spectrum.truth)
    truth["F_N_R"] = truth["F_N"] * truth["R"]
    truth["k_c"] = 2.0 * truth["E_star"] * truth["a"]
    return truth


def _minimize(problem: _Problem, theta0):
    """L-BFGS-B with tight tolerances: the likelihood is very narrow in a (a relative 1e-4 shifts
    the modulation's phase at the band's top), and a looser ftol stopped it early there."""
    bounds = list(zip(problem.lower, problem.upper))
    return scipy.optimize.minimize(problem.objective, theta0, method="L-BFGS-B", bounds=bounds,
                                   options={"maxiter": 2000, "ftol": 1e-15, "gtol": 1e-10, "maxfun": 20000})


def _derived(problem: _Problem, theta, cov) -> dict:
    """Derived quantities (:func:`mdroll.inverse.forward_model.derived`, and lambda A on the line's grid
    when known), with delta-method 95 % intervals (in log scale)."""
    units = {"k_c": "N/m", "omega_0": "rad/s", "F_N_R": "N m", "F_N": "N", "level": "Pa^2 m^(2-2H)",
             "lambda_A": "m^(2-2H)"}

    def values(t):
        p = problem.params(t)
        out = derived(p)
        out["lambda_A"] = lambda_A(p["h0"], p["H"], p["q_min"], p["q_max"], problem.setting.line_length)
        if problem.spectrum.quantity == "force":
            out.pop("omega_0")
        if "R" not in problem.free and "R" not in problem.fixed:
            out.pop("F_N")
        return out

    centre = values(theta)
    gradients = {name: np.zeros(len(theta)) for name in centre}
    for k in range(len(theta)):
        h = 1e-6 * max(1.0, abs(theta[k]))
        up, down = theta.copy(), theta.copy()
        up[k] += h
        down[k] -= h
        vu, vd = values(up), values(down)
        for name in centre:
            gradients[name][k] = (math.log(vu[name]) - math.log(vd[name])) / (2 * h)
    out = {}
    for name, value in centre.items():
        with np.errstate(invalid="ignore"):
            variance = float(gradients[name] @ cov @ gradients[name])
        sd = math.sqrt(variance) if math.isfinite(variance) and variance >= 0 else math.inf
        ends = [value * math.exp(-Z95 * sd), value * math.exp(Z95 * sd)] if sd < 300.0 else [0.0, math.inf]
        out[name] = {"value": value, "ci95": ends,
                     "unit": units[name]}
    return out


def _profiles(problem: _Problem, theta, f_hat, sd, scale, points) -> dict:
    out = {}
    kappa_n = 2.0 * problem.kappa * problem.data.size
    for i, name in enumerate(problem.free):
        width = sd[i] if np.isfinite(sd[i]) and sd[i] > 0 else 0.1
        grid = theta[i] + np.linspace(-4.0, 4.0, points) * width
        grid = np.clip(grid, problem.lower[i], problem.upper[i])
        others = [j for j in range(len(theta)) if j != i]
        deltas = []
        for value in grid:
            def restricted(rest, value=value):
                full = theta.copy()
                full[i] = value
                full[others] = rest
                return problem.objective(full)

            if others:
                res = scipy.optimize.minimize(restricted, theta[others], method="L-BFGS-B",
                                              bounds=[(problem.lower[j], problem.upper[j]) for j in others],
                                              options={"maxiter": 500, "ftol": 1e-15, "gtol": 1e-10})
                f = res.fun
            else:
                f = restricted(np.zeros(0))
            deltas.append(kappa_n * (f - f_hat) / scale)
        values = [_from_fitted(name, g) for g in grid]
        out[name] = {"values": values, "delta": deltas, "ci95": _profile_interval(values, deltas, i, theta, name)}
    return out


def _profile_interval(values, deltas, i, theta, name):
    """Where the profile crosses chi^2_1(0.95) = 3.84 on each side of its minimum (linear
    interpolation); None on a side where it stays below (an open interval)."""
    d = np.asarray(deltas)
    centre = int(np.argmin(d))
    ends = []
    for side in (range(centre, -1, -1), range(centre, len(d))):
        side = list(side)
        crossing = None
        for a, b in zip(side[:-1], side[1:]):
            if d[a] < CHI2_95 <= d[b]:
                t = (CHI2_95 - d[a]) / (d[b] - d[a])
                crossing = values[a] + t * (values[b] - values[a])
                break
        ends.append(crossing)
    return ends


# ---------------------------------------------------------------------------------- starting values
def _starting_values(problem: _Problem, start: dict) -> dict:
    """Data-driven starting values for the free parameters (``start`` overrides them)."""
    unknown = set(start) - set(problem.free)
    if unknown:
        raise ParameterError(f"start names {sorted(unknown)}, which are not free ({', '.join(problem.free)})")
    free = set(problem.free) - set(start)
    p = dict(problem.fixed)
    p.update({"H": 0.6, "q_min": problem.omega[0] / problem.v0, "a": 5e-3, "E_star": 1.15e11, "h0": 1e-6, "R": 0.5,
              "m": 500.0, "zeta": 0.02, "low_scale": 1.0, "noise": 0.0, "leak": 0.0, **problem.fixed})
    p.update(start)
    omega, data = problem.omega, problem.data
    v0 = problem.v0
    top = data[-max(1, data.size // 20):]

    # the resonance from the whole spectrum (the default band starts above it)
    spectrum = problem.spectrum
    resonance = find_resonance(spectrum.omega, spectrum.psd) if spectrum.quantity == "accel" else None
    # power law of the upper two thirds (log) of the band: P ~ omega^-(2H+3)
    upper = omega >= omega[0] * (omega[-1] / omega[0]) ** (1.0 / 3.0)
    upper &= data > 0
    if resonance is not None:
        upper &= omega > 3.0 * resonance
    if upper.sum() >= 8:
        x, y = np.log(omega[upper]), np.log(data[upper])
        top_half = x >= 0.5 * (x[0] + x[-1])
        slope = np.polyfit(x[top_half], y[top_half], 1)[0]
        if "H" in free:
            p["H"] = float(np.clip((-slope - 3.0) / 2.0, 0.05, 0.95))
        if "a" in free:
            p["a"] = _modulation_radius(omega[upper] / v0, np.log(data[upper]), default=p["a"])
    if "a_jitter" in free:  # the edge displacement of eq 47 at the RMS height
        p["a_jitter"] = float(edge_displacement(p["h0"], p["R"], p["a"]))
    if "noise" in free:
        p["noise"] = 0.3 * float(np.median(top))
    if "leak" in free:
        p["leak"] = 0.01 * float(np.median(top)) * omega[-1] ** 2
    if "E_star" in free and resonance is not None and problem.spectrum.quantity == "accel":
        p["E_star"] = p["m"] * resonance**2 / (2.0 * p["a"])
    level = "h0" if "h0" in free else ("E_star" if "E_star" in free and problem.spectrum.quantity == "force" else None)

    def scaled(trial):  # the objective with the level profiled out analytically (S = s g)
        g = problem.model(_with_load(problem, trial))
        if not np.all(np.isfinite(g)) or np.any(g <= 0):
            return _HUGE, 1.0
        s = float(np.mean(data / g))
        return float(np.mean(np.log(s * g) + data / (s * g))), s

    if "E_star" in free and resonance is None and spectrum.quantity == "accel":
        candidates = np.geomspace(1e9, 1e13, 41)
        p["E_star"] = float(candidates[int(np.argmin([scaled(dict(p, E_star=float(e)))[0] for e in candidates]))])
    if "q_min" in free:
        candidates = np.geomspace(omega[0] / v0, omega[-1] / v0 / 3.0, 48)
        scores = [scaled(dict(p, q_min=float(q)))[0] for q in candidates]
        p["q_min"] = float(candidates[int(np.argmin(scores))])
        # then at the bins' resolution: the likelihood has a kink at every bin, where a gradient
        # method stalls (q_min -6.5 % at q_min = 2 pi / 10 mm, L = 1 m, K = 10 without this)
        bin_q = problem.setting.bin_width / v0
        fine = p["q_min"] + bin_q * np.arange(-0.1 * p["q_min"] / bin_q, 0.1 * p["q_min"] / bin_q, 0.5)
        fine = fine[fine > 0]
        scores = [scaled(dict(p, q_min=float(q)))[0] for q in fine]
        p["q_min"] = float(fine[int(np.argmin(scores))])
    if "a" in free:
        # a fine scan around the start, in steps of a quarter of the phase tolerance pi / (8 q_top)
        step = math.pi / (32.0 * omega[-1] / v0)
        trials = [a for a in p["a"] + step * np.arange(-16, 17) if a > 0]
        p["a"] = float(trials[int(np.argmin([scaled(dict(p, a=float(a)))[0] for a in trials]))])
    if level is not None:
        s = scaled(p)[1]
        p[level] *= math.sqrt(s)
    return _with_load(problem, p)


def _with_load(problem: _Problem, p: dict) -> dict:
    if problem.load is not None:
        p = dict(p, a=float(contact_radius_from_load(problem.load, p["E_star"], p["R"])))
    return p


def _modulation_radius(q, log_psd, default, smallest=1e-3):
    """a from the modulation of eq 40 and eq 48 (period pi / a in q, eq 26): ``log sin^2(q a)``
    less its running mean over 2 pi / ``smallest`` (m) is ``-2 sum_k cos(2 k q a) / k``, whose
    fundamental lies at a / pi cycles per rad/m: the peak of its periodogram (resampled on a
    uniform q grid, Hann taper, 8x zero padding), for a above ``smallest`` / 2."""
    if q.size < 16:
        return default
    size = min(q.size, 2**18)
    grid = np.linspace(q[0], q[-1], size)
    step = grid[1] - grid[0]
    values = np.interp(grid, q, log_psd)
    width = int(min(size // 4, max(3, round(TWO_PI / smallest / step)))) | 1
    r = values - scipy.ndimage.uniform_filter1d(values, width, mode="nearest")
    r = (r - r.mean()) * np.hanning(size)
    spectrum = np.abs(np.fft.rfft(r, 8 * size)) ** 2
    cycles = np.fft.rfftfreq(8 * size, step)
    radius = math.pi * cycles
    usable = (cycles > 4.0 / (q[-1] - q[0])) & (radius > 0.5 * smallest) & (cycles < 0.25 / step)
    if not usable.any():
        return default
    return float(radius[usable][np.argmax(spectrum[usable])])


def find_resonance(omega, data, sharpness: float = 5.0):
    """The contact resonance of an acceleration spectrum (rad/s), or None: among the 500 largest
    local maxima of the lower half (log) of ``omega``, the one whose PSD exceeds most the larger of the
    medians over its neighbours within 5 % (at least 3 bins) below and above, if by ``sharpness``
    times: a resonance falls steeply on both sides; the onset of the high band at q_min v0 and
    the broad lobes of sin^2(q a) do not."""
    lower = np.flatnonzero(omega <= math.sqrt(omega[0] * omega[-1]))
    if lower.size < 3:
        return None
    lower = lower[(lower > 0) & (lower < data.size - 1)]
    peaks = lower[(data[lower] > data[lower - 1]) & (data[lower] >= data[lower + 1])]
    candidates = peaks[np.argsort(data[peaks])[-500:]]
    best, best_ratio = None, 0.0
    for k in candidates:
        width = max(3, int(np.searchsorted(omega, 1.05 * omega[k]) - k))
        left, right = data[max(0, k - width):k], data[k + 1:k + 1 + width]
        if left.size == 0 or right.size == 0:
            continue
        ratio = data[k] / max(float(np.median(left)), float(np.median(right)), 1e-300)
        if ratio > best_ratio and 0 < k < data.size - 1:
            best, best_ratio = k, ratio
    return float(omega[best]) if best is not None and best_ratio >= sharpness else None
