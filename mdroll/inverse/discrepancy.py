"""The model discrepancy of a closed-form fit: the bias a table cannot simulate away, as an uncertainty.

A table carries no simulation settings, so its fit keeps the closed form, whose ratio r(q) to the
exact MDR spectrum is taken as unknown: ``log r(q) = c0 + c1 log2(q / q_mid)`` (q_mid the band's
geometric middle, in rad/m) with c0 and c1 independent, of mean 0 and standard deviations
(level, tilt per octave), at the knots of :func:`mdroll.inverse.correction.knots` over the band.
The fit holds r = 1 with that covariance as its correction (:func:`prior`), so the estimate does
not move and the correction's delta method (:mod:`.intervals`) widens the intervals;
:func:`with_discrepancy` then records it as a discrepancy instead of a correction
(docs/inverse.md, "The model discrepancy of a table").
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..errors import ParameterError
from .correction import knots
from .forward_model import PARAMETERS, Correction
from .intervals import Z95
from .likelihood import from_fitted, to_fitted
from .observed import Spectrum
from .result import FitResult

#: The default (level, tilt per octave) for a table fitted with the closed form alone: the root
#: mean squares of the least-squares intercept and slope of log r that the simulated correction
#: measured over the round-trip grid at K >= 100, rounded up (docs/inverse.md, "The model
#: discrepancy of a table").
DISCREPANCY = (0.03, 0.02)


def discrepancy_sigma(discrepancy, mode: str, spectrum: Spectrum) -> tuple | None:
    """The (level, tilt) of :func:`~mdroll.inverse.fit.fit`'s ``discrepancy``, checked, or None for
    none: the default's rule (:data:`DISCREPANCY` for the closed form of a spectrum without
    simulation settings); an explicit one only with the closed form alone (``mode`` "none")."""
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


def prior(band_q, sigma: tuple) -> Correction:
    """r = 1 at the knots over ``band_q`` (rad/m), with the covariance of its log values that
    ``sigma`` = (level, tilt) gives (the module docstring)."""
    positions = knots(band_q)
    octaves = (np.asarray(positions) - np.mean(positions)) / math.log(2.0)
    basis = np.column_stack([np.ones_like(octaves), octaves])  # knot values = basis @ (c0, c1)
    return Correction(positions, (0.0,) * len(positions),
                      tuple(map(tuple, (basis @ np.diag(np.square(sigma)) @ basis.T).tolist())))


def with_discrepancy(result: FitResult, sigma: tuple) -> FitResult:
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
        theta = to_fitted(name, result.estimates[name])
        without[name] = [from_fitted(name, theta - Z95 * local), from_fitted(name, theta + Z95 * local)]
    return dataclasses.replace(result, correction=None, discrepancy={
        "level": sigma[0], "tilt": sigma[1], "q_knots": record["q_knots"], "variance_fitted_scale": added,
        "widening": widening, "ci95_without": without})
