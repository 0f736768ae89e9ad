"""The covariance of the estimate, its 95 % intervals and those of derived quantities.

The expected Fisher information of the Whittle likelihood (:mod:`.likelihood`) is
``I = kappa * J^T J`` with ``J_jk = d log S_j / d theta_k`` (central differences). Simulated
and measured spectra are rarely exactly chi-square: fixed-amplitude lines scatter less, a
window correlates neighbouring bins (Hann: the variance of a sum over bins is 1.94x the
independent one), and the model is not exact. So the covariance reported is the quasi-likelihood
one, ``phi * tau * I^-1``, with the Pearson dispersion phi and the long-run variance factor tau
of the standardized residuals (:func:`mdroll.inverse.likelihood.goodness_of_fit`), which covers
the correlation of neighbouring bins and a smooth misfit of the model over many bins alike; the
raw ``I^-1`` intervals are kept as ``ci95_fisher``. A cutoff (q_min, q_max) is located to within
a bin of width dq at best: its variance gets the uniform ``(dq / q)^2 / 12`` (in log scale)
added. A correction r(q) of the model (simulated, :mod:`.correction`, or the discrepancy of a
table, :mod:`.discrepancy`) adds its own uncertainty by the delta method
(:func:`correction_covariance`), and its gain (the fixed point's amplification) multiplies the
standard errors. Intervals are symmetric in the fitted (log) scale; derived quantities get
delta-method intervals in log scale (:func:`derived_quantities`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import scipy.stats

from .forward_model import PARAMETERS, derived, lambda_A
from .likelihood import Problem, from_fitted, log_jacobian

Z95 = scipy.stats.norm.ppf(0.975)


def covariance(problem: Problem, theta, scale: float):
    """The covariance of the estimate ``theta`` (fitted scale) of the module docstring, with
    ``scale`` = phi tau: returns it, the raw ``I^-1`` (with the cutoffs' resolution), the
    correction's part and the names of the unidentified parameters."""
    jac = problem.log_model_jacobian(theta)
    information = problem.kappa * jac.T @ jac
    raw_cov, unidentified = inverse_information(information, problem.free)
    # r's part by the delta method with I^-1 itself, before the cutoffs' resolution is added:
    # that is a variance of the estimate, not information, and has no place in G
    correction_cov = correction_covariance(problem, theta, raw_cov, jac, unidentified)
    cov = scale * raw_cov
    for name in ("q_min", "q_max"):  # a cutoff is located to within a bin: its uniform variance
        if name in problem.free and name not in unidentified:
            i = problem.free.index(name)
            resolution = (problem.setting.bin_width / problem.v0 / from_fitted(name, theta[i])) ** 2 / 12.0
            cov[i, i] += resolution
            raw_cov[i, i] += resolution
    cov = cov + correction_cov
    if problem.setting.correction is not None and problem.setting.correction.gain:
        gain = np.asarray(problem.setting.correction.gain)
        cov = cov * np.outer(gain, gain)
    return cov, raw_cov, correction_cov, unidentified


def inverse_information(information, names):
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


def correction_covariance(problem: Problem, theta, raw_cov, jac, unidentified) -> np.ndarray:
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


def correction_record(problem: Problem, correction_cov) -> dict | None:
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


def intervals(free, theta, estimates: dict, sd) -> tuple[dict, dict]:
    """The 95 % intervals, symmetric in the fitted scale, and the standard errors (SI) of the free
    parameters from their standard deviations ``sd`` in the fitted scale; unbounded where sd is
    not finite (an unidentified parameter)."""
    ci, stderr = {}, {}
    for i, name in enumerate(free):
        if not np.isfinite(sd[i]):
            ci[name] = (0.0, math.inf) if PARAMETERS[name][1] == "log" else (-math.inf, math.inf)
            stderr[name] = math.inf
            continue
        ci[name] = (from_fitted(name, theta[i] - Z95 * sd[i]), from_fitted(name, theta[i] + Z95 * sd[i]))
        stderr[name] = sd[i] * (estimates[name] if PARAMETERS[name][1] == "log" else 1.0)
    return ci, stderr


def derived_quantities(problem: Problem, theta, cov) -> dict:
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
    gradients = log_jacobian(lambda t: np.array([values(t)[name] for name in centre]), theta, 1e-6)
    out = {}
    for gradient, (name, value) in zip(gradients, centre.items()):
        with np.errstate(invalid="ignore"):
            variance = float(gradient @ cov @ gradient)
        sd = math.sqrt(variance) if math.isfinite(variance) and variance >= 0 else math.inf
        ends = [value * math.exp(-Z95 * sd), value * math.exp(Z95 * sd)] if sd < 300.0 else [0.0, math.inf]
        out[name] = {"value": value, "ci95": ends,
                     "unit": units[name]}
    return out
