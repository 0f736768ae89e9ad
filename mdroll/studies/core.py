"""What every thesis study shares: the claim and its verdict, the study's result, the runner that
records every ensemble it runs, the fits with confidence intervals and the curves of its figures
(the figures themselves are :class:`mdroll.experiments.Figure`).

A :class:`Claim` holds a thesis claim, the number it is tested against (the thesis's own, or a
closed form of physics.md where the thesis gives none), the measured value and its standard
error from the ensembles. Its verdict is

- ``disagrees`` when ``|measured - expected| > allowance + Z_SIGMA * stderr``;
- ``not resolved at this size`` when it does not disagree but ``Z_SIGMA * stderr`` exceeds the
  claim's ``resolution`` (the smallest discrepancy that matters): the ensemble is too small to
  tell;
- ``agrees`` otherwise; ``reported`` for a measured number with nothing to test it against.

A disagreement is never hidden: a claim the project knows to fail (a convention factor, a
thesis observation the measurement contradicts) carries its explanation in ``known``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..ensemble.measure import Z_SIGMA
from ..ensemble.spec import EnsembleSpec, run_specs

AGREES, DISAGREES, UNRESOLVED, REPORTED = "agrees", "disagrees", "not resolved at this size", "reported"


@dataclass
class Claim:
    """One thesis claim against one measurement (see the module docstring for the verdict).

    ``expected`` is the number tested against and ``source`` says whose it is ("thesis",
    "closed form", ...); ``allowance`` (same unit) is the stated model allowance; ``resolution``
    the smallest discrepancy worth resolving (default: the allowance, or 5 % of |expected|).
    """

    name: str
    thesis: str
    measured: float
    stderr: float
    expected: float | None = None
    unit: str = "-"
    source: str = "thesis"
    allowance: float = 0.0
    resolution: float | None = None
    known: str = ""
    note: str = ""

    @property
    def verdict(self) -> str:
        if self.expected is None or not math.isfinite(self.expected):
            return REPORTED
        deviation = abs(self.measured - self.expected)
        if not math.isfinite(deviation) or deviation > self.allowance + Z_SIGMA * self.stderr:
            return DISAGREES
        resolution = self.resolution if self.resolution is not None else (self.allowance or 0.05 * abs(self.expected))
        return UNRESOLVED if Z_SIGMA * self.stderr > resolution else AGREES

    def as_dict(self) -> dict:
        return {"name": self.name, "thesis": self.thesis, "measured": self.measured, "stderr": self.stderr,
                "expected": self.expected, "source": self.source, "unit": self.unit, "allowance": self.allowance,
                "resolution": self.resolution, "verdict": self.verdict, "known": self.known, "note": self.note}


def claims_by(claims: list, prefix: str) -> tuple[float, float]:
    """(measured, stderr) of the first claim whose name starts with ``prefix``."""
    claim = next(c for c in claims if c.name.startswith(prefix))
    return claim.measured, claim.stderr


@dataclass
class StudyOutcome:
    """What a study function returns: its claims, every measured number (JSON-ready, with
    standard errors), its figures (:class:`mdroll.experiments.Figure`), a sentence on what the
    statistics can resolve and a summary of the findings, written from the measured numbers."""

    claims: list
    measurements: dict
    figures: list
    resolution: str = ""
    summary: str = ""


class Runner:
    """The studies' access to :func:`mdroll.run_specs`: one seed and device for the whole study,
    and a record of every ensemble run (spec, steps, device, timings) for the JSON. ``cluster``:
    a runner for ``run_specs(..., runner=)`` (e.g. :class:`mdroll.distributed.DaskRunner`)."""

    def __init__(self, device: str = "cpu", seed: int = 0, progress: bool = False, cluster=None):
        self.device = device
        self.seed = seed
        self.progress = progress
        self.cluster = cluster
        self.record: list = []

    def spec(self, params, realizations: int, **settings) -> EnsembleSpec:
        """A spec of ``realizations`` realizations from index 0 at this study's seed: decoupled,
        open and the registry's default algorithm of the mode (the fastest exact one,
        :data:`mdroll.forces.registry.DEFAULT_ALGORITHMS`) unless ``settings`` say otherwise."""
        return EnsembleSpec(params=params, seed=self.seed, realizations=realizations, **settings)

    def run(self, specs: list) -> list:
        """Run ``specs`` with :func:`mdroll.run_specs` and record them; the results in order."""
        start = time.perf_counter()
        results = run_specs(specs, device=self.device, progress=self.progress, runner=self.cluster)
        elapsed = (time.perf_counter() - start) / max(1, len(specs))
        for spec, result in zip(specs, results):
            self.record.append({"spec": spec.as_dict(), "steps": result.steps, "device": result.device,
                                "contact_lost_steps": result.contact_lost_steps,
                                "force_rms_N": result.force_rms, "seconds_each": elapsed,
                                "timings_s": result.timings})
        return results


# ---------------------------------------------------------------------------- fits
def fit_line(x, y, sigma) -> tuple[np.ndarray, np.ndarray, float]:
    """Weighted least squares ``y = c0 + c1 x`` with absolute standard errors ``sigma``
    (scipy.optimize.curve_fit): ``(c0, c1)``, their covariance and the reduced chi^2."""
    from scipy.optimize import curve_fit

    x, y, sigma = (np.asarray(v, dtype=np.float64) for v in (x, y, sigma))
    slope0, intercept0 = np.polyfit(x, y, 1)
    popt, pcov = curve_fit(lambda t, c0, c1: c0 + c1 * t, x, y, p0=(intercept0, slope0), sigma=sigma,
                           absolute_sigma=True)
    chi2 = float(np.sum(((y - popt[0] - popt[1] * x) / sigma) ** 2) / max(1, x.size - 2))
    return popt, pcov, chi2


def fit_power_law(x, y, rel_err) -> tuple[float, float, float, float]:
    """``y = C x^p`` by weighted least squares on logs (relative errors ``rel_err`` of y):
    ``(p, stderr p, C, stderr C)``."""
    popt, pcov, _ = fit_line(np.log(x), np.log(y), rel_err)
    constant = math.exp(popt[0])
    return float(popt[1]), float(math.sqrt(pcov[1, 1])), constant, constant * float(math.sqrt(pcov[0, 0]))


def ratio_stderr(x: float, sx: float, y: float, sy: float, cov: float = 0.0) -> tuple[float, float]:
    """``x / y`` and its standard error by the delta method (``cov`` the covariance of x and y)."""
    r = x / y
    return r, abs(r) * math.sqrt(max((sx / x) ** 2 + (sy / y) ** 2 - 2 * cov / (x * y), 0.0))


# ---------------------------------------------------------------------------- plots
def loglog(ax, x, y, err=None, label=None, **style):
    """Log-log curve of the positive points of ``y`` on ``x`` with a +-1 standard-error band."""
    keep = (x > 0) & (y > 0)
    line, = ax.loglog(x[keep], y[keep], lw=style.pop("lw", 0.7), label=label, **style)
    if err is not None:
        ax.fill_between(x[keep], np.maximum(y - err, y * 1e-3)[keep], (y + err)[keep], color=line.get_color(),
                        alpha=0.25, lw=0)
    return line


def mark(ax, x, text, color="0.45"):
    """A dotted vertical line at ``x`` labelled ``text`` at the top of the axes."""
    ax.axvline(x, color=color, ls=":", lw=0.8)
    ax.text(x, 0.98, f" {text}", transform=ax.get_xaxis_transform(), rotation=90, va="top", ha="right",
            fontsize=7, color=color)
