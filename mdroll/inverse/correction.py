"""The simulated correction of the closed-form model: what eq 40 and eq 48 leave out.

The forward model of :mod:`mdroll.inverse.forward_model` is the linear part of the contact force (eq
40) with the contact-radius jitter, and the quadratic low band (eq 48). The exact MDR force of
the simulator has more: the non-linear part of the contact force, which tilts the high band
(physics.md section 7: eq 40 within 1 % to 24 q_min, 6 % to 96 q_min). A slope of a few per cent
over the band is what a change of H of about 0.01 makes, so the closed form alone biases H (and
through the response h0 and E*) by more than the statistical error of a large K.

The correction measures that part by simulation. At the current estimate theta, an ensemble of
K_c passes (the data's L, dx, boundary and window; the seed :data:`SEED`; K_c = 32, or more to
roll 80 m on a short line) is simulated through
:func:`mdroll.run_specs`, and the smoothed ratio

    r(q) = E[simulated PSD at theta] / S_closed_form(theta; q),
    log r(q) = sum_k c_k b_k(log q)                        (b_k: hat functions, knots an octave apart)

is estimated by the Whittle likelihood of the simulated spectrum with theta held (a Gamma GLM
with log link, convex in c; its covariance ``phi tau (kappa_c B^T B)^-1`` calibrated like the
fit's own). The data are then refitted with ``r(q) S(theta)`` and r re-measured at the new
estimate: the fixed point theta* = argmin -log L(theta; r(theta*)) has E[simulated PSD at theta*]
= E[data] when the data come from the simulator, so the bias of the closed form goes, to the
extent r changes with theta between the iterates. The intervals add r's uncertainty by the
delta method: ``cov += G cov_c G^T``, ``G = d theta_hat / d c = -I^-1 kappa J^T J_c``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.optimize

from ..ensemble.spec import EnsembleSpec
from ..errors import ParameterError
from ..params import Params
from ..physics import TWO_PI
from .forward_model import PARAMETERS, Correction, expected_psd, load_times_radius, setting_for
from .likelihood import long_run_factor
from .observed import from_result

#: Master seed of the correction's simulations (the same at every iteration: common random
#: numbers, so that the iterates differ by the change of the estimate, not by noise).
SEED = 2_000_003
#: Passes K_c of a correction's ensemble, at least: the ratio is smoothed over octaves of many
#: bins, so its statistical error stays below the data's at K_c much smaller than K.
PASSES = 32
#: ... and at least this rolled distance K_c L (m): the octave at the band's bottom holds few bins
#: on a short line (24 at L = 0.5 m), and its noise reaches h0 and E* through the response
#: (docs/inverse.md, "The simulated correction": their errors with 32 and 160 passes at 0.5 m).
DISTANCE = 80.0
#: Knot spacing of log r, in octaves of q.
OCTAVES = 1.0
#: At most this many iterations (simulate at the estimate, refit): the map from one estimate to
#: the next contracts by about 0.35 where the non-linearity is strongest and by 0.1 at the
#: defaults (docs/inverse.md, "The simulated correction"), so a step of the sixth is below 1 % of
#: the first.
ITERATIONS = 6
#: The correction is not simulated where the estimate's contact radius exceeds this fraction of R
#: (Hertz's small-contact assumption, d0 = a^2 / R << R, fails; the one-pass fits that wander there
#: would also cost a simulation with a / dx springs in contact).
LARGEST_CONTACT = 0.1
#: Stop when every free parameter moves by less than this many standard errors.
TOLERANCE = 0.1


def simulation_params(estimates: dict, sim: dict) -> Params:
    """The Params of a simulation at ``estimates`` (SI, with v0): E from E* with the simulation's nu
    (eq 1-2), F_N = 4 a^3 E* / (3 R) (eq 14-15), the simulation's L and dx, q_min on the line's
    grid (the nearest 2 pi k / L)."""
    e = estimates
    E = e["E_star"] * 2.0 * (1.0 - sim["nu"] ** 2)
    # the lines hold the grid's modes 2 pi k / L only: q_min on the grid point nearest the estimate
    dq = TWO_PI / (round(sim["L"] / sim["dx"]) * sim["dx"])
    return Params(E=E, nu=sim["nu"], R=e["R"], m=e["m"], F_N=load_times_radius(e["a"], e["E_star"]) / e["R"],
                  v0=e["v0"], L=sim["L"], dx=sim["dx"], h0=e["h0"], H=e["H"],
                  q_min=max(1, round(e["q_min"] / dq)) * dq)


def knots(band_q, octaves: float = OCTAVES) -> tuple:
    """log q of the knots of log r: evenly spaced in log q from the band's bottom to its top, about
    ``octaves`` apart, at least two."""
    low, high = math.log(band_q[0]), math.log(band_q[1])
    count = max(2, math.ceil((high - low) / (octaves * math.log(2.0))) + 1)
    return tuple(np.linspace(low, high, count).tolist())


def hat_basis(q, knot_positions) -> np.ndarray:
    """(n, k): the hat functions of :class:`~mdroll.inverse.forward_model.Correction` at ``q`` (rad/m),
    so that ``log r(q) = hat_basis(q) @ log_ratio``."""
    x = np.log(np.asarray(q, dtype=np.float64))
    eye = np.eye(len(knot_positions))
    return np.column_stack([np.interp(x, knot_positions, eye[k]) for k in range(len(knot_positions))])


def estimate_ratio(data, model, basis, kappa: float) -> tuple[np.ndarray, np.ndarray]:
    """The Whittle (Gamma, log-link) fit of ``data ~ model exp(basis @ c)``: c and its calibrated
    covariance ``phi tau (kappa B^T B)^-1`` (phi the Pearson dispersion, tau the long-run factor
    of :func:`mdroll.inverse.likelihood.long_run_factor`). Convex in c: Newton's method from c = 0."""
    ratio = data / model
    start = np.zeros(basis.shape[1])

    def objective(c):
        g = basis @ c
        return float(np.mean(g + ratio * np.exp(-g)))

    def gradient(c):
        return basis.T @ (1.0 - ratio * np.exp(-(basis @ c))) / ratio.size

    def hessian(c):
        return (basis * (ratio * np.exp(-(basis @ c)))[:, None]).T @ basis / ratio.size

    c = scipy.optimize.minimize(objective, start, jac=gradient, hess=hessian, method="trust-exact").x
    z = math.sqrt(kappa) * (ratio * np.exp(-(basis @ c)) - 1.0)
    phi = float(np.sum(z * z) / max(z.size - c.size, 1))
    tau = long_run_factor(z)[0]
    return c, phi * tau * np.linalg.inv(kappa * basis.T @ basis)


def default_passes(spectrum) -> int:
    """K_c for ``spectrum``: :data:`PASSES`, or more to roll :data:`DISTANCE` in all on its line."""
    return max(PASSES, math.ceil(DISTANCE / spectrum.simulation["L"]))


def correction_spec(spectrum, estimates: dict, passes: int = PASSES, seed: int = SEED) -> EnsembleSpec:
    """The ensemble that measures r at ``estimates`` (the full parameter set of the model, SI, with
    v0): ``passes`` realizations with the spectrum's ``simulation`` settings (L, dx, nu, and
    optionally boundary, mode, algorithm) and window; master seed ``seed`` plus the data's own seed when it
    has one (independent of the data's realizations, and of other data's corrections)."""
    sim = spectrum.simulation
    if estimates["a"] > LARGEST_CONTACT * estimates["R"]:
        raise ParameterError(f"the estimate a = {estimates['a']:.4g} m exceeds {LARGEST_CONTACT:g} R: beyond Hertz's "
                             "small contact, nothing to simulate")
    return EnsembleSpec(simulation_params(estimates, sim), seed=seed + int(sim.get("seed", 0)),
                        realizations=passes, boundary=sim.get("boundary", "open"), mode=sim.get("mode", "decoupled"),
                        algorithm=sim.get("algorithm"), window=spectrum.window)


def measured_correction(ensemble, spectrum, estimates: dict, band) -> Correction:
    """r(q) over ``band`` (rad/s) from the ``ensemble`` of :func:`correction_spec`, against the
    closed-form model at the same parameters (``estimates``, with the simulation's q_min on the
    line's grid and its q_max) evaluated in the simulation's own setting (its dt, L and window;
    the estimate's leakage, which the simulated series has too; no noise floor): a :class:`~mdroll.inverse.forward_model.Correction` with the
    covariance of its log values (:func:`estimate_ratio`, kappa = the ensemble's passes)."""
    simulated = from_result(ensemble, spectrum.quantity, spectrum.window)
    v0 = estimates["v0"]
    inside = (simulated.omega >= band[0]) & (simulated.omega <= band[1])
    omega = simulated.omega[inside]
    p = dict(estimates, q_min=ensemble.params.q_min, q_max=ensemble.params.q_max, noise=0.0)
    model = expected_psd(omega, p, setting_for(simulated, v0))
    positions = knots((omega[0] / v0, omega[-1] / v0))
    c, covariance = estimate_ratio(simulated.psd[inside], model, hat_basis(omega / v0, positions), simulated.passes)
    return Correction(positions, tuple(c.tolist()), tuple(map(tuple, covariance.tolist())))


def iterate(spectra, results, refit, simulate, passes: int | None = None, iterations: int = ITERATIONS,
            tolerance: float = TOLERANCE) -> list:
    """The fixed point of the module docstring for several fits at once: measure r at each current
    estimate (one :func:`correction_spec` each, of ``passes`` or :func:`default_passes`, run
    together by ``simulate(specs) -> ensembles``),
    refit with it (``refit(jobs) -> results``, jobs ``(spectrum, previous result, correction)``),
    until every free parameter moves by less than ``tolerance`` of its standard error (at most
    ``iterations`` times). ``results``: the closed form's fits; returns the corrected ones, each
    with ``correction["iterates"]`` (the estimates before each step) and ``["converged"]``."""
    results = list(results)
    history = [[_free_values(r)] for r in results]
    skipped = {}
    for i, result in enumerate(results):
        bound = _at_bound(result)
        if bound:
            skipped[i] = f"the estimate of {bound} lies at its bound"
    active = [i for i in range(len(results)) if i not in skipped]
    for _ in range(iterations):
        specs = {}
        for i in active:
            try:
                specs[i] = correction_spec(spectra[i], _model_values(results[i]), passes or default_passes(spectra[i]))
            except ParameterError as error:  # an estimate no simulation can hold
                skipped[i] = str(error)
        active = list(specs)
        if not active:
            break
        ensembles = simulate(list(specs.values()))
        jobs = [(spectra[i], results[i],
                 dataclasses.replace(measured_correction(e, spectra[i], _model_values(results[i]), results[i].band),
                                     gain=_gain(history[i], results[i], tolerance)))
                for i, e in zip(active, ensembles)]
        still = []
        for i, new in zip(active, refit(jobs)):
            if not _settled(results[i], new, tolerance):
                still.append(i)
            results[i] = new
            history[i].append(_free_values(new))
        active = still
    # the gain measured on the last steps, where the last fit had not had it yet (it changes the
    # intervals only: the refit starts and stays at the estimate)
    stale = [i for i, r in enumerate(results) if r.correction_used is not None
             and r.correction_used.gain != _gain(history[i], r, tolerance)]
    jobs = [(spectra[i], results[i], dataclasses.replace(results[i].correction_used,
                                                         gain=_gain(history[i], results[i], tolerance))) for i in stale]
    for i, new in zip(stale, refit(jobs) if jobs else []):
        results[i] = new
    for i, result in enumerate(results):
        if result.correction is None:  # skipped before any correction: the closed form's fit stays
            result.correction = {"iterates": history[i], "converged": False}
        else:
            result.correction.update(iterates=history[i][:-1], converged=i not in active and i not in skipped)
        if i in skipped:
            result.correction["skipped"] = skipped[i]
    return results


def _gain(history, result, tolerance: float) -> tuple:
    """1 / (1 - rho) per free parameter, rho the ratio of the last two steps of the iterates
    ``history`` (fitted scale), clipped to [0, 0.8]; 1 with fewer than two steps or where the
    earlier step was below ``tolerance`` standard errors of ``result`` (too small to measure rho
    on). At the fixed point theta* = F(theta*, data), a change of the data that moves one fit with
    r held by d moves theta* by d / (1 - rho) (rho = dF/dtheta, along each parameter)."""
    if len(history) < 3:
        return tuple(1.0 for _ in result.free)
    out = []
    for name in result.free:
        values = [_fitted(name, h[name]) for h in history[-3:]]
        before, last = values[1] - values[0], values[2] - values[1]
        scale = result.stderr[name] / (result.estimates[name] if PARAMETERS[name][1] == "log" else 1.0)
        rho = last / before if abs(before) > tolerance * scale else 0.0
        out.append(1.0 / (1.0 - min(max(rho, 0.0), 0.8)))
    return tuple(out)


def _fitted(name: str, value: float) -> float:
    return math.log(value) if PARAMETERS[name][1] == "log" else value


def _at_bound(result) -> str | None:
    """The first free parameter whose estimate lies at a bound of
    :data:`~mdroll.inverse.forward_model.PARAMETERS` (a fit that wandered off), or None."""
    for name in result.free:
        _, _, low, high = PARAMETERS[name]
        if not low * (1 + 1e-6) < result.estimates[name] < high * (1 - 1e-6):
            return name
    return None


def _model_values(result) -> dict:
    return {**result.estimates, "v0": result.known["v0"]}


def _free_values(result) -> dict:
    return {n: result.estimates[n] for n in result.free}


def _settled(old, new, tolerance: float) -> bool:
    """Whether every free parameter moved by at most ``tolerance`` standard errors (in its fitted
    scale: relative for the positive ones)."""
    for name in new.free:
        step = _fitted(name, new.estimates[name]) - _fitted(name, old.estimates[name])
        scale = new.stderr[name] / (new.estimates[name] if PARAMETERS[name][1] == "log" else 1.0)
        if math.isfinite(scale) and abs(step) > tolerance * scale:
            return False
    return True
