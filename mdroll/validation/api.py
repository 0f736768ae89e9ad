"""The check API: an ensemble spec, a prediction, a band, a comparison and a tolerance.

A :class:`Check` compares an ensemble (:class:`~mdroll.EnsembleSpec`) with an analytic
prediction, a callable ``prediction(x, params)`` of the band's bins ``x`` (wavenumbers q in
rad/m for a band in q, angular frequencies omega = q v0 in rad/s for a band in omega) and the
ensemble's :class:`~mdroll.Params`. It returns

- a PSD on ``x`` (N^2 m for the force, (m/s^2)^2 m for the acceleration; physics.md section 6)
  for ``comparison="ratio"``: measured is the band-averaged ratio
  ``sum_band C_measured / sum_band C_predicted``, predicted 1;
- a scalar for the other comparisons: ``"slope"`` (of the period-averaged PSD against q in
  log-log, eq 23; absolute tolerance), ``"period"`` (of the modulation of C q^(2H+3), rad/m,
  eq 26), ``"peak"`` (position of the largest bin, rad/m or rad/s), or ``"ratio"`` with a
  ``reference`` ensemble: the band sum of ``spec`` over that of ``reference`` (say 4 for a
  doubled h0, eq 28).

The tolerance is the stated model ``allowance`` (relative, absolute for slopes) plus ``k``
standard errors of the measured ratio taken from the ensemble itself (physics.md section 7):
a small ensemble gets a wider tolerance, never a tuned one. With ``paired=True`` the standard
error comes from the scatter of per-realization band sums (realization by realization against
a ``reference`` of the same seed and realizations); otherwise from the per-bin standard errors,
bins taken as independent. Slopes, periods and peaks are read off the mean spectrum: their
tolerance is the allowance alone.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..ensemble import measure
from ..ensemble.measure import Z_SIGMA, band_sum, independent_ratio, paired_ratio, period_bands
from ..ensemble.resolution import REASONS, estimator_name
from ..ensemble.spec import EnsembleSpec
from ..errors import ParameterError, PredictionError
from ..params import Params
from ..physics import BAND_EDGE_TOLERANCE
from .plots import spectrum_plot

COMPARISONS = ("ratio", "slope", "period", "peak")
QUANTITIES = ("force", "accel")
#: Band units: multiples of q_min or of omega_0, or absolute (rad/m on the q axis, rad/s on omega).
BAND_UNITS = ("q_min", "rad/m", "omega_0", "rad/s")


@dataclass
class CheckResult:
    """One validation record.

    ``passed`` is ``|ratio - 1| <= tolerance < 1`` with ``ratio > 0`` for relative checks
    (``kind="relative"``: a tolerance of 100 % or more, which a ratio near 0 would meet, fails
    as too wide to test the claim),
    ``|measured - predicted| <= tolerance`` for ``kind="absolute"`` and ``measured >= predicted``
    for ``kind="minimum"``; ``kind="report"`` records a measured property and passes when it is
    finite. ``details`` holds extra numbers worth keeping; ``plot`` draws the figure on an Axes.
    """

    name: str
    equation: str
    measured: float
    predicted: float
    tolerance: float
    kind: str
    unit: str
    note: str
    details: dict = field(default_factory=dict)
    plot: Callable | None = field(default=None, repr=False, compare=False)

    @property
    def ratio(self) -> float:
        """measured / predicted; NaN where the prediction is 0 (the JSON then holds null)."""
        return self.measured / self.predicted if self.predicted else math.nan

    @property
    def passed(self) -> bool:
        if self.kind == "relative":  # a positive ratio within a tolerance that can fail it (< 100 %)
            return self.ratio > 0 and abs(self.ratio - 1.0) <= self.tolerance < 1.0
        if self.kind == "absolute":
            return abs(self.measured - self.predicted) <= self.tolerance
        if self.kind == "minimum":
            return self.measured >= self.predicted
        return math.isfinite(self.measured)

    def tolerance_text(self) -> str:
        return {"relative": f"+-{100 * self.tolerance:.1f}%", "absolute": f"+-{self.tolerance:.3g}",
                "minimum": f">= {self.predicted:.3g}", "report": "report"}[self.kind]

    def as_dict(self) -> dict:
        return {"name": self.name, "equation": self.equation, "measured": self.measured, "predicted": self.predicted,
                "ratio": self.ratio if math.isfinite(self.ratio) else None, "tolerance": self.tolerance, "kind": self.kind, "unit": self.unit,
                "passed": self.passed, "note": self.note, "details": self.details}


@dataclass(frozen=True)
class Band:
    """The bins ``0 < x``, ``lo <= x < hi`` in ``unit`` (:data:`BAND_UNITS`); with ``whole_periods``
    the whole modulation periods pi/a from ``lo`` up to ``hi`` (eq 26)."""

    lo: float
    hi: float
    unit: str = "q_min"
    whole_periods: bool = False

    def __post_init__(self) -> None:
        if self.unit not in BAND_UNITS:
            raise ParameterError(f"band unit = {self.unit!r} is not allowed: choose one of {', '.join(BAND_UNITS)}")
        if not (math.isfinite(self.lo) and math.isfinite(self.hi) and 0 <= self.lo < self.hi):
            raise ParameterError(f"band = [{self.lo!r}, {self.hi!r}] is not allowed: it needs 0 <= lo < hi, finite")

    @property
    def on_omega(self) -> bool:
        return self.unit in ("omega_0", "rad/s")

    def limits(self, params: Params) -> tuple[float, float]:
        """The band's ends in rad/m (q axis) or rad/s (omega axis)."""
        scale = {"q_min": params.q_min, "omega_0": params.omega_0}.get(self.unit, 1.0)
        return self.lo * scale, self.hi * scale

    def axis(self, result):
        return result.omega if self.on_omega else result.q

    def mask(self, x: np.ndarray, params: Params) -> np.ndarray:
        lo, hi = self.limits(params)
        if self.whole_periods:
            return np.logical_or.reduce(period_bands(x / (params.v0 if self.on_omega else 1.0), lo, hi, params.a))
        return (x >= lo * (1 - BAND_EDGE_TOLERANCE)) & (x < hi) & (x > 0)

    def text(self) -> str:
        return f"[{self.lo:g}, {self.hi:g}] {self.unit}" + (" (whole periods)" if self.whole_periods else "")


def call_prediction(name: str, prediction, x: np.ndarray, params: Params):
    """``prediction(x, params)`` as float64 (a scalar, or an array shaped as ``x``), or a
    :class:`PredictionError` naming the check when it raises or is not finite."""
    try:
        returned = prediction(x, params)
    except SystemExit as exc:  # sys.exit in a prediction must not end mdroll as a success
        raise PredictionError(f"check {name!r}: its prediction called sys.exit({exc.code!r})") from None
    except Exception as exc:  # a user's prediction may fail in any way: bad input, named
        raise PredictionError(f"check {name!r}: its prediction raised {type(exc).__name__}: {exc}") from None
    try:
        value = np.asarray(returned, dtype=np.float64)
    except (TypeError, ValueError):
        raise PredictionError(f"check {name!r}: its prediction returned {str(returned)[:40]!r} "
                              f"({type(returned).__name__}), not a number or an array of numbers") from None
    if value.ndim and value.shape != x.shape:
        raise PredictionError(f"check {name!r}: its prediction returned shape {value.shape}, "
                              f"expected a scalar or {x.shape}")
    if not np.all(np.isfinite(value)):
        raise PredictionError(f"check {name!r}: its prediction returned NaN or infinity")
    return value if value.ndim else float(value)


@dataclass(frozen=True)
class Check:
    """A user's or a built-in check (module docstring): ``spec`` against ``prediction`` on ``band``.

    ``spec``: the ensemble (None for a check used only to :meth:`evaluate` given results).
    ``quantity``: the force or the acceleration PSD. ``reference``: a second ensemble for a
    scalar ratio. ``allowance`` and ``k``: the tolerance. ``paired``: standard errors from
    per-realization band sums (force only). ``equation``, ``unit`` and ``note`` label the result.
    """

    name: str
    spec: EnsembleSpec | None
    prediction: Callable
    band: Band
    comparison: str = "ratio"
    allowance: float = 0.05
    k: float = Z_SIGMA
    quantity: str = "force"
    reference: EnsembleSpec | None = None
    paired: bool = False
    equation: str = ""
    unit: str = "-"
    note: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ParameterError(f"check name = {self.name!r} is not allowed: give a non-empty text")
        for label in ("allowance", "k"):
            value = getattr(self, label)
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ParameterError(f"check {self.name!r}: {label} = {value!r} is not allowed: it must be a number")
        if self.comparison not in COMPARISONS:
            raise ParameterError(f"comparison = {self.comparison!r} is not allowed: choose one of "
                                 f"{', '.join(COMPARISONS)}")
        if self.quantity not in QUANTITIES:
            raise ParameterError(f"quantity = {self.quantity!r} is not allowed: choose one of {', '.join(QUANTITIES)}")
        if not (self.allowance >= 0 and self.k >= 0 and math.isfinite(self.allowance) and math.isfinite(self.k)):
            raise ParameterError(f"check {self.name!r}: allowance = {self.allowance!r} and k = {self.k!r} must be "
                                 "finite and >= 0")
        if self.comparison != "slope" and self.allowance >= 1:
            raise ParameterError(f"check {self.name!r}: allowance = {self.allowance!r} is not allowed for a relative "
                                 "comparison: below 1 (100 %), or a ratio near 0 would pass")
        for label in ("spec", "reference"):
            value = getattr(self, label)
            if value is not None and not isinstance(value, EnsembleSpec):
                raise ParameterError(f"check {self.name!r}: {label} = {value!r} must be an mdroll.EnsembleSpec or None")
        if not isinstance(self.band, Band):
            raise ParameterError(f"check {self.name!r}: band = {self.band!r} must be a mdroll.validation.Band")
        if self.comparison in ("slope", "period") and self.band.on_omega:
            raise ParameterError(f"check {self.name!r}: a {self.comparison} is measured on q: give its band in q_min "
                                 f"or rad/m, not {self.band.unit}")
        if self.paired and self.quantity != "force":
            raise ParameterError(f"check {self.name!r}: paired = True needs quantity = 'force' (per-realization rows "
                                 "are kept of the force PSD)")
        if not callable(self.prediction):
            raise ParameterError(f"check {self.name!r}: prediction = {self.prediction!r} is not callable")

    def specs(self) -> list[EnsembleSpec]:
        return [self.spec] + ([self.reference] if self.reference is not None else [])

    def run(self, source) -> CheckResult:
        """Run or load the ensembles from ``source`` (:class:`~mdroll.validation.ensembles.EnsembleSource`)
        and compare."""
        if self.paired:
            hi = self.band.limits(self.spec.params)[1] / (self.spec.params.v0 if self.band.on_omega else 1.0)
            measured = source.paired(self.spec, hi)
            reference = source.paired(self.reference, hi) if self.reference else None
        else:
            measured = source.result(self.spec)
            reference = source.result(self.reference) if self.reference else None
        return self.evaluate(measured, reference)

    def evaluate(self, measured, reference=None) -> CheckResult:
        """Compare a measured ensemble (an :class:`~mdroll.EnsembleResult`, or a
        :class:`~mdroll.validation.ensembles.Paired` for ``paired``) with the prediction; the
        band's bins the record cannot resolve (:mod:`mdroll.ensemble.resolution`; for a
        resonance peak, other than its main lobe) are counted in ``details`` and warned of in the note."""
        outcome = self._evaluate(measured, reference)
        result = getattr(measured, "result", measured)
        if not hasattr(result, "resolution"):  # spectra without a record (arrays a user built): nothing flagged
            return outcome
        flags = result.resolution.reasons[self.quantity]
        mask = self.band.mask(self.band.axis(result), result.params)
        flagged = mask & (flags >= 0) & ~((flags == REASONS.index("within the window's main lobe of omega_0"))
                                          & (self.comparison == "peak"))
        if flagged.any():
            outcome.details["unresolved_bins_in_band"] = int(flagged.sum())
            outcome.note += (f"; warning: {int(flagged.sum())} of the band's {int(mask.sum())} bins are unresolved by "
                             f"this record ({estimator_name(result.window)})")
        return outcome

    def _evaluate(self, measured, reference=None) -> CheckResult:
        result = getattr(measured, "result", measured)
        params = result.params
        x = self.band.axis(result)
        mask = self.band.mask(x, params)
        if not mask.any():
            raise ParameterError(f"check {self.name!r}: band {self.band.text()} holds no bins of the ensemble")
        predicted = call_prediction(self.name, self.prediction, x[mask], params)
        psd = getattr(result, f"{self.quantity}_psd")
        stderr = getattr(result, f"{self.quantity}_psd_stderr")
        band = self.band.text()
        if self.comparison == "ratio":
            value, rel = self._ratio(measured, reference, psd, stderr, predicted, mask)
            if np.ndim(predicted):
                curve = np.full_like(psd, np.nan)
                curve[mask] = predicted
                return self._result(params, value, 1.0, self.allowance + self.k * rel, "relative",
                                    f"measured / predicted {self.quantity} PSD summed over {band}", x, psd, curve)
            return self._result(params, value, predicted, self.allowance + self.k * rel, "relative",
                                f"{self.quantity} PSD summed over {band}, over the reference ensemble's", x, psd)
        if np.ndim(predicted):
            raise PredictionError(f"check {self.name!r}: a {self.comparison} prediction must be a scalar, "
                                  f"got an array of shape {np.shape(predicted)}")
        lo, hi = self.band.limits(params)
        if self.comparison == "slope":
            value = measure.period_averaged_slope(result.q, psd, params.a, lo, hi)[0]
            return self._result(params, value, predicted, self.allowance, "absolute",
                                f"least-squares slope of the period-averaged {self.quantity} PSD on {band}", x, psd)
        if self.comparison == "period":
            value = measure.modulation_period(result.q, psd, params.H, lo, hi)
            return self._result(params, value, predicted, self.allowance, "relative",
                                f"autocorrelation period of C q^(2H+3) on {band}, bin width {x[1] - x[0]:.3g}", x, psd)
        value = measure.resonance_peak(x, psd, 1.0, lo, hi)
        return self._result(params, value, predicted, self.allowance, "relative",
                            f"largest {self.quantity} PSD bin in {band}, bin width {x[1] - x[0]:.3g}", x, psd)

    def _ratio(self, measured, reference, psd, stderr, predicted, mask):
        """The band ratio and its relative standard error (module docstring)."""
        if reference is None:
            if not np.ndim(predicted):
                raise PredictionError(f"check {self.name!r}: a scalar ratio needs a reference ensemble")
            if self.paired:
                return paired_ratio(measured.band_sums(mask), predicted.sum())
            total, rel = band_sum(psd, stderr, mask)
            return total / predicted.sum(), rel
        if self.paired:
            return paired_ratio(measured.band_sums(mask), reference.band_sums(mask))
        other = getattr(reference, f"{self.quantity}_psd"), getattr(reference, f"{self.quantity}_psd_stderr")
        return independent_ratio(*band_sum(psd, stderr, mask), *band_sum(*other, mask))

    def _result(self, params, measured, predicted, tolerance, kind, note, x, psd, curve=None) -> CheckResult:
        curves = [(self.quantity, psd, None)] + ([("prediction", curve, None)] if curve is not None else [])
        lo, hi = self.band.limits(params)
        return CheckResult(self.name, self.equation, float(measured), float(predicted), float(tolerance), kind,
                           self.unit, self.note or note, plot=spectrum_plot(x, curves, marks=[("lo", lo), ("hi", hi)],
                                                                            xlabel="omega (rad/s)" if self.band.on_omega else "q (rad/m)"))
