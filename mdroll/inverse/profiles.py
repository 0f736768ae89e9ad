"""Profile likelihoods of the free parameters: a check of the local (Fisher) intervals.

For each free parameter, the others are re-fitted on a grid of +-4 calibrated standard errors
around the estimate, and the profile is the deviance difference divided by phi tau (the
quasi-likelihood scale of :mod:`.intervals`). Its 95 % interval lies where it crosses
chi^2_1(0.95) = 3.84; a profile that stays below on a side is an open interval (a degeneracy or
a weakly identified direction), and a profile that dips below its estimate's value says the
search stopped short of the minimum.
"""

from __future__ import annotations

import numpy as np
import scipy.optimize
import scipy.stats

from .likelihood import Problem, from_fitted

CHI2_95 = scipy.stats.chi2.ppf(0.95, 1)


def profiles(problem: Problem, theta, f_hat, sd, scale, points) -> dict:
    """``{name: {"values": [...], "delta": [...], "ci95": [lo, hi]}}`` over ``points`` values of
    each free parameter around the estimate ``theta`` (objective ``f_hat``, standard deviations
    ``sd`` in the fitted scale, ``scale`` = phi tau)."""
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
        values = [from_fitted(name, g) for g in grid]
        out[name] = {"values": values, "delta": deltas, "ci95": _profile_interval(values, deltas)}
    return out


def _profile_interval(values, deltas):
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
