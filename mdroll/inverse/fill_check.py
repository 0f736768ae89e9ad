"""The fill check: how far the estimate moves when the contact-radius jitter is held at eq 47.

A white noise floor fills the zeros of sin^2(q a) as the jitter of the contact radius does. Free
together, they can trade, and the high band's level, hence h0 and E*, follows them beyond what
the local intervals say; where the data separate them, the fitted jitter is eq 47's edge
displacement ``h0 R / (2 a)`` (docs/inverse.md, "The fill check: when the floor and the jitter
trade"). So the check refits with a_jitter held there, ``s_a = h0 R / (2 a)`` of the refit's own
estimate (iterated to that fixed point; the other parameters free, the correction held), and
widens the covariance (fitted scale) by the shift d of the free parameters, ``cov + d d^T``
(a_jitter's own: from its fitted value to eq 47's).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..physics import edge_displacement
from .intervals import derived_quantities, intervals
from .likelihood import Problem, to_fitted
from .observed import Spectrum
from .result import FitResult

#: When the fill check runs (:func:`~mdroll.inverse.fit.fit`'s ``fill_check``): "auto" where the noise
#: floor and the contact-radius jitter are both free (the two nuisances that fill the zeros of
#: sin^2(q a)), "on" wherever the jitter is free, "off" never.
FILL_CHECKS = ("auto", "on", "off")
#: The fill check's refits hold a_jitter at eq 47's h R / (2 a) of their own estimate: at most
#: this many, until it changes by less than :data:`FILL_CHECK_TOLERANCE` (relative).
FILL_CHECK_ITERATIONS = 5
FILL_CHECK_TOLERANCE = 1e-3


def with_fill_check(spectrum: Spectrum, result: FitResult, bin: int, mode: str, refit) -> FitResult:
    """``result`` with the fill check of the module docstring where it applies (``mode``,
    :data:`FILL_CHECKS`), recorded in ``result.fill_check``; ``result`` itself elsewhere.
    ``refit`` is :func:`mdroll.inverse.fit.fit` (passed in: this check sits below the fit it repeats)."""
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
        tied = refit(spectrum, known={**result.known, "a_jitter": jitter}, free=free, band=result.band,
                     passes=None if result.passes_assumed else result.passes, bin=bin,
                     start={n: p[n] for n in free}, profile=False,
                     correction=held, fill_check="off")
    values = {**{n: tied.estimates[n] for n in free}, "a_jitter": jitter}
    shift = np.array([to_fitted(n, values[n]) - to_fitted(n, result.estimates[n]) for n in result.free])
    problem = Problem(spectrum, result.known, result.free, result.band,
                      None if result.passes_assumed else result.passes, bin, result.correction_used)
    theta = problem.theta(result.estimates)
    cov = result.covariance + np.outer(shift, shift)
    sd = np.sqrt(np.abs(np.diag(cov)))
    before = dict(result.stderr)
    ci, stderr = intervals(result.free, theta, result.estimates, sd)
    with np.errstate(invalid="ignore", divide="ignore"):
        correlation = cov / np.outer(sd, sd)
    record = {"rule": mode, "a_jitter_fitted": result.estimates["a_jitter"], "a_jitter_edge": jitter,
              "estimates_held": values, "shift_fitted_scale": dict(zip(result.free, shift.tolist())),
              "stderr_local": before, "ci95_local": {n: list(v) for n, v in result.ci95.items()},
              "widening": {n: stderr[n] / before[n] if 0 < before[n] < math.inf else 1.0 for n in result.free}}
    return dataclasses.replace(result, covariance=cov, correlation=correlation, stderr=stderr, ci95=ci,
                               derived=derived_quantities(problem, theta, cov), fill_check=record)
