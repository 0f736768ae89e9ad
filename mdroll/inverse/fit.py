"""The Whittle fit of an averaged spectrum: :func:`fit` runs the pieces of the package in turn.

1. The band's data and the Whittle likelihood (:mod:`.likelihood`, over the band of
   :mod:`.band`); for a table, the model discrepancy held as a correction (:mod:`.discrepancy`).
2. Data-driven starting values (:mod:`.starting_values`), then scipy.optimize L-BFGS-B in the
   fitted scale, a scan of q_min over quarter bins, and L-BFGS-B again (:func:`estimate`).
3. At the estimate: the goodness of fit, the calibrated covariance and 95 % intervals and those
   of derived quantities (:mod:`.intervals`), the profile likelihoods (:mod:`.profiles`).
4. For an mdroll spectrum, the simulated correction of the closed form (:mod:`.correction`),
   iterated to its fixed point by refits (:func:`refit`).
5. The fill check (:mod:`.fill_check`), where the noise floor and the jitter can trade.
6. The acceptance gate (:mod:`.acceptance`): a fit whose model the data reject, or whose band
   the record cannot resolve, is marked ``accepted = False`` with the reasons.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.optimize

from ..arguments import check_integer
from ..ensemble.spec import run_specs
from ..errors import ParameterError
from .acceptance import acceptance
from .correction import iterate
from .discrepancy import discrepancy_sigma, prior, with_discrepancy
from .fill_check import FILL_CHECKS, with_fill_check
from .forward_model import Correction
from .intervals import correction_record, covariance, derived_quantities, intervals
from .likelihood import Problem, from_fitted, goodness_of_fit, to_fitted
from .observed import MAX_PASSES, Spectrum
from .profiles import profiles
from .result import FitResult
from .starting_values import starting_values


def fit(spectrum: Spectrum, known: dict | None = None, free=None, band=None, passes: int | None = None,
        bin: int = 1, start: dict | None = None, profile: bool = True, profile_points: int = 9,
        correction=None, correction_passes: int | None = None, device: str = "auto", runner=None,
        fill_check: str = "auto", discrepancy: float | None = None) -> FitResult:
    """Fit the forward model (:mod:`mdroll.inverse.forward_model`) to ``spectrum`` by the Whittle
    likelihood (:mod:`mdroll.inverse.likelihood`).

    Parameters
    ----------
    spectrum : :class:`~mdroll.inverse.observed.Spectrum` (see :func:`~mdroll.inverse.read_spectrum`).
    known : ``{name: value}`` in SI units: any of :data:`~mdroll.inverse.forward_model.PARAMETERS`
        and ``v0`` (m/s), ``E`` (Pa) with ``nu``, ``F_N`` (N; a then follows from R and E*, eq 14-15).
    free : names to fit (default :func:`~mdroll.inverse.forward_model.default_free`).
    band : (omega_lo, omega_hi) in rad/s (default: :func:`~mdroll.inverse.band.resolve_band`'s).
    passes : K, the number of averaged passes (default the spectrum's, else 1, marked assumed).
    bin : average this many neighbouring bins first (nu = 2 K bin).
    start : starting values for some free parameters (SI), instead of the data-driven ones.
    profile : compute the profile likelihood of each free parameter (``profile_points`` each).
    correction : "simulated" (the default for a spectrum that carries its simulation's settings,
        an mdroll one, on the rigid rail; not allowed on a known track, whose default is "none"): the closed form times the ratio r(q) that simulations at the estimate
        measure (:mod:`mdroll.inverse.correction`), iterated, with r's uncertainty in the
        intervals; "none" (the default for a table): the closed form alone; or a
        :class:`~mdroll.inverse.forward_model.Correction` to hold fixed (e.g.
        ``result.correction_used``).
    correction_passes : passes K_c of each correction ensemble (default
        :func:`mdroll.inverse.correction.default_passes`: 32, or more to roll 80 m). device,
        runner : where those ensembles run (:func:`mdroll.run_specs`).
    fill_check : "auto" (default), "on" or "off" (:data:`~mdroll.inverse.fill_check.FILL_CHECKS`):
        refit with a_jitter held at the edge displacement of eq 47, ``h0 R / (2 a)`` of the refit's
        own estimate, and add the shift of every free parameter to its variance
        (:mod:`mdroll.inverse.fill_check`); "auto" where the noise floor and a_jitter are both
        free, "on" wherever a_jitter is free.
    discrepancy : (level, tilt) >= 0, the closed form's unknown discrepancy with correction "none":
        ``log r(q) = c0 + c1 log2(q / q_mid)`` (q_mid the band's geometric middle, in rad/m) with
        c0 and c1 of mean 0 and standard deviations level and tilt (per octave), at knots an
        octave apart over the band, added to the covariance by the delta method
        (:func:`~mdroll.inverse.intervals.correction_covariance`) and recorded in
        ``result.discrepancy``; None (default): :data:`~mdroll.inverse.discrepancy.DISCREPANCY`
        for a table (a spectrum without the simulation's settings, which the simulated correction
        needs), none otherwise; 0: none.

    Returns a :class:`~mdroll.inverse.result.FitResult`. Bad input ends with a ParameterError naming it.
    """
    _check_arguments(spectrum, known, free, passes, bin, correction_passes)
    if fill_check not in FILL_CHECKS:
        raise ParameterError(f"fill_check = {fill_check!r} is not allowed: use one of {', '.join(map(repr, FILL_CHECKS))}")
    mode = _correction_mode(correction, spectrum)
    simulate = mode == "simulated"
    sigma = discrepancy_sigma(discrepancy, mode, spectrum)
    if simulate and not {"L", "dx", "nu"} <= set(spectrum.simulation):
        raise ParameterError("correction = 'simulated' needs the simulation's L, dx and nu (an mdroll spectrum, or a "
                             "table given simulation={'L': ..., 'dx': ..., 'nu': ...}); use correction='none' otherwise")
    problem = Problem(spectrum, known, free, band, passes, bin,
                      correction if isinstance(correction, Correction) else None)
    if sigma:
        band_q = (problem.omega[0] / problem.v0, problem.omega[-1] / problem.v0)
        problem.setting = dataclasses.replace(problem.setting, correction=prior(band_q, sigma))
    p0 = starting_values(problem, start or {})
    theta, best = estimate(problem, np.clip(problem.theta(p0), problem.lower, problem.upper))
    if simulate:
        closed_form = _result(problem, theta, best, spectrum, profile=False, profile_points=profile_points)
        result = iterate([spectrum], [closed_form], refit=lambda jobs: [refit(job, bin) for job in jobs],
                         simulate=lambda specs: run_specs(specs, device=device, runner=runner),
                         passes=correction_passes)[0]
        if profile:
            final = result
            result = refit((spectrum, final, final.correction_used), bin, profile=True, profile_points=profile_points)
            result.correction = {**(result.correction or {}), **final.correction}
    else:
        result = _result(problem, theta, best, spectrum, profile, profile_points)
        if sigma:
            result = with_discrepancy(result, sigma)
    result = with_fill_check(spectrum, result, bin, fill_check, refit=fit)
    result.acceptance = acceptance(result.gof, result.band, spectrum, result.discrepancy)
    return result


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


def estimate(problem: Problem, theta0):
    """The maximum-likelihood estimate from ``theta0``: L-BFGS-B, the cutoff's scan, L-BFGS-B again
    (restarted: its first stop is often early, or on a bin's kink)."""
    best = _minimize(problem, theta0)
    best = _minimize(problem, _polish_cutoff(problem, best.x))
    return best.x, best


def _minimize(problem: Problem, theta0):
    """L-BFGS-B with tight tolerances: the likelihood is very narrow in a (a relative 1e-4 shifts
    the modulation's phase at the band's top), where a looser ftol stops short of the optimum."""
    bounds = list(zip(problem.lower, problem.upper))
    return scipy.optimize.minimize(problem.objective, theta0, method="L-BFGS-B", bounds=bounds,
                                   options={"maxiter": 2000, "ftol": 1e-15, "gtol": 1e-10, "maxfun": 20000})


def _polish_cutoff(problem: Problem, theta):
    """q_min by a scan over +-3 bins in quarter bins, the other parameters held: the likelihood has
    a kink at every bin (the fractional bin weight of :func:`~mdroll.inverse.forward_model.band_weights`)."""
    if "q_min" not in problem.free:
        return theta
    i = problem.free.index("q_min")
    bin_q = problem.setting.bin_width / problem.v0
    centre = from_fitted("q_min", theta[i])
    best, best_f = theta, problem.objective(theta)
    for q in centre + bin_q * np.arange(-3.0, 3.01, 0.25):
        if q <= 0:
            continue
        trial = theta.copy()
        trial[i] = to_fitted("q_min", q)
        f = problem.objective(trial)
        if f < best_f:
            best, best_f = trial, f
    return best


def _result(problem: Problem, theta, best, spectrum: Spectrum, profile: bool, profile_points: int) -> FitResult:
    """The FitResult at the estimate ``theta``: intervals, goodness of fit, profiles."""
    f_hat = problem.objective(theta)
    S = problem.model(problem.params(theta))
    gof = goodness_of_fit(problem.data, S, problem.kappa, len(problem.free))
    scale = gof["phi"] * gof["tau"]
    cov, raw_cov, correction_cov, unidentified = covariance(problem, theta, scale)
    sd = np.sqrt(np.abs(np.diag(cov)))
    sd_raw = np.sqrt(np.abs(np.diag(raw_cov)))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    estimates = problem.params(theta)
    ci, stderr = intervals(problem.free, theta, estimates, sd)
    ci_raw = intervals(problem.free, theta, estimates, np.where(np.isfinite(sd), sd_raw, np.inf))[0]
    gof.update(nll_per_bin=f_hat, unidentified=unidentified)

    result = FitResult(
        free=problem.free, estimates=estimates, known=problem.known, stderr=stderr, ci95=ci, ci95_fisher=ci_raw,
        covariance=cov, correlation=corr, derived=derived_quantities(problem, theta, cov), gof=gof,
        band=problem.band, kappa=problem.kappa, passes=problem.passes, passes_assumed=problem.passes_assumed,
        success=bool(best.success), message=str(best.message), omega=problem.omega, data=problem.data, model=S,
        quantity=spectrum.quantity, truth=_truth_of(spectrum), correction=correction_record(problem, correction_cov),
        correction_used=problem.setting.correction,
    )
    if profile:
        result.profiles = profiles(problem, theta, f_hat, sd, scale, profile_points)
        lower = min((min(v["delta"]) for v in result.profiles.values()), default=0.0)
        result.gof["profile_found_lower_minimum"] = bool(lower < -0.5)
    return result


def _check_arguments(spectrum, known, free, passes, bin, correction_passes) -> None:
    """The types of :func:`fit`'s arguments and the bounds of its counts, each named in a
    ParameterError (the other values are checked where they are used)."""
    if not isinstance(spectrum, Spectrum):
        raise ParameterError(f"spectrum must be an mdroll.inverse.Spectrum (read_spectrum, table_spectrum or "
                             f"from_result), got {type(spectrum).__name__}")
    if known is not None and not isinstance(known, dict):
        raise ParameterError(f"known must be a dict {{name: value}}, got {type(known).__name__}")
    if free is not None and (isinstance(free, str) or not isinstance(free, (list, tuple))
                             or not all(isinstance(n, str) for n in free)):
        raise ParameterError(f"free = {free!r} is not allowed: give a list of parameter names, e.g. ['H', 'h0']")
    for name, value, maximum in (("passes", passes, MAX_PASSES), ("bin", bin, None),
                                 ("correction_passes", correction_passes, MAX_PASSES)):
        if value is not None:
            check_integer(name, value, 1, maximum=maximum)


def _correction_mode(correction, spectrum: Spectrum) -> str:
    if spectrum.known_track is not None and correction is not None and not isinstance(correction, Correction) \
            and correction == "simulated":
        raise ParameterError("correction = 'simulated' is not allowed on a known track: its ensembles roll on the rigid "
                             "rail; use 'none' (the linear chain, for roughness small against d0)")
    if correction is None:
        return "simulated" if spectrum.simulation and spectrum.known_track is None else "none"
    if isinstance(correction, Correction):
        return "fixed"
    if correction not in ("simulated", "none"):
        raise ParameterError(f"correction = {correction!r} is not allowed: use 'simulated', 'none' or a Correction")
    return correction


def _truth_of(spectrum: Spectrum) -> dict | None:
    if not spectrum.truth:
        return None
    truth = dict(spectrum.truth)
    truth["F_N_R"] = truth["F_N"] * truth["R"]
    truth["k_c"] = 2.0 * truth["E_star"] * truth["a"]
    return truth
