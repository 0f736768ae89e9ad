"""The outcome of a fit: :class:`FitResult`, its JSON record and its text table."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..files import jsonable
from .forward_model import PARAMETERS, Correction


@dataclass
class FitResult:
    """The outcome of :func:`~mdroll.inverse.fit.fit`. Values in SI units (see
    :data:`~mdroll.inverse.forward_model.PARAMETERS`).

    ``estimates``: every model parameter (free ones estimated, the rest as fixed); ``ci95``,
    ``stderr``: the free ones' calibrated 95 % intervals and standard errors; ``ci95_fisher``: the
    uncalibrated ones (:mod:`.intervals`); ``derived``: derived quantities with delta-method
    intervals; ``gof``: goodness of fit (:func:`~mdroll.inverse.likelihood.goodness_of_fit`);
    ``profiles``: ``{name: {"values": [...], "delta": [...], "ci95": [lo, hi]}}`` (:mod:`.profiles`).
    ``acceptance``: the gate of :mod:`.acceptance` (``accepted``, ``reasons``, ``notes``, ...);
    ``success`` is the optimizer's convergence; :attr:`accepted` both.
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
    acceptance: dict | None = None

    @property
    def accepted(self) -> bool:
        """The gate (:mod:`.acceptance`) accepts the fit. An optimizer that stops short of its
        own convergence test (L-BFGS-B's ABNORMAL line search at the precision limit) is a
        warning, not a rejection: the gate judges the fit by its residuals either way."""
        return self.acceptance is None or self.acceptance["accepted"]

    @property
    def rejection(self) -> str:
        """Why the fit is not accepted, in one line (empty when it is)."""
        if self.accepted:
            return ""
        return "; ".join((self.acceptance or {}).get("reasons", []))

    def to_dict(self) -> dict:
        """A JSON-ready dict (arrays as lists; the band's data and model included)."""
        out = {
            "free": self.free, "estimates": self.estimates, "known": self.known, "stderr": self.stderr,
            "ci95": {k: list(v) for k, v in self.ci95.items()},
            "ci95_fisher": {k: list(v) for k, v in self.ci95_fisher.items()},
            "correlation": self.correlation.tolist(), "covariance_fitted_scale": self.covariance.tolist(),
            "fitted_scale": {n: PARAMETERS[n][1] for n in self.free},
            "derived": self.derived, "gof": self.gof, "band_rad_s": list(self.band), "kappa": self.kappa,
            "passes": self.passes, "passes_assumed": self.passes_assumed, "accepted": self.accepted,
            "rejected_because": self.rejection, "success": self.accepted, "optimizer_success": self.success,
            "acceptance": self.acceptance, "message": self.message, "quantity": self.quantity,
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
        gate = self.acceptance
        if gate:
            lines.append(("accepted" if self.accepted else "REJECTED") + f" at the {gate['level']:g} level"
                         + (f" (misfit p {gate['misfit_p']:.3g})" if gate["misfit_p"] is not None else "")
                         + (f": {self.rejection}" if not self.accepted else ""))
            lines += [f"note: {note}" for note in gate["notes"]]
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
