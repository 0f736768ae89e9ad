"""The Whittle likelihood of an averaged spectrum over its band, and its goodness of fit.

A periodogram bin of a Gaussian series is its expected value S times chi^2_2 / 2; the mean of
K independent passes is ``S chi^2_nu / nu`` with nu = 2K degrees of freedom, a Gamma variable of
shape kappa = nu / 2. Averaging B neighbouring bins (``bin=B``) gives nu = 2 K B when the bins
are independent (the model is averaged over the same bins). The negative log-likelihood used, up
to terms free of the parameters, is

    -log L(theta) = kappa * sum_j [ log S_j(theta) + P_j / S_j(theta) ]          (Whittle)

over the bins j in the band; the estimate does not depend on kappa. Positive parameters are
fitted as their logarithms (H as is), bounded (:data:`mdroll.inverse.forward_model.PARAMETERS`):
:class:`Problem` holds the band's data and the objective in that fitted scale.

Goodness of fit (:func:`goodness_of_fit`): the Gamma deviance ``D = 2 kappa sum (P/S - log(P/S)
- 1)`` against chi^2 with n - p degrees of freedom, the Pearson dispersion ``phi = sum z_j^2 / (n
- p)`` of the standardized residuals ``z_j = sqrt(kappa) (P_j / S_j - 1)``, their long-run
variance factor tau (:func:`long_run_factor`), and a Kolmogorov-Smirnov test of P/S against the
Gamma law.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.stats

from ..errors import ParameterError
from .band import resolve_band
from .forward_model import (NUISANCE_DEFAULTS, PARAMETERS, Correction, check_free, contact_radius_from_load,
                            default_free, expected_psd, resolve_known, setting_for)
from .observed import Spectrum

#: Block sizes (bins) of the batch-means estimate of the residuals' long-run variance: powers of
#: 2 while at least 16 blocks fit.
BLOCK_SIZES = tuple(2**i for i in range(24))
MIN_BINS_PER_PARAMETER = 5
MIN_BINS = 10
#: The objective's value where the model is not finite and positive: the searches step back.
HUGE = 1e30


class Problem:
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
        self.band = resolve_band(band, spectrum)
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
        with_power = int(np.sum(self.data >= np.finfo(np.float64).tiny))
        if with_power < needed_bins:
            raise ParameterError(f"band {self.band[0]:.6g}..{self.band[1]:.6g} rad/s holds {with_power} bins with power "
                                 f"(PSD above {np.finfo(np.float64).tiny:.3g}); at least {needed_bins} are needed for "
                                 f"{len(self.free)} free parameters: the spectrum is zero there")
        self.passes_assumed = passes is None and spectrum.passes is None
        self.passes = int(passes if passes is not None else (spectrum.passes or 1))
        self.kappa = self.passes * bin_size
        self.setting = setting_for(spectrum, v0, correction)
        positive = self.data > 0
        self.offset = float(np.mean(np.log(self.data[positive]))) + 1.0 if positive.any() else 0.0
        self.lower = np.array([to_fitted(n, PARAMETERS[n][2]) for n in self.free])
        self.upper = np.array([to_fitted(n, PARAMETERS[n][3]) for n in self.free])

    # ------------------------------------------------------------------ parameters
    def params(self, theta) -> dict:
        p = dict(self.fixed)
        p.update({n: from_fitted(n, t) for n, t in zip(self.free, theta)})
        if self.load is not None:
            p["a"] = float(contact_radius_from_load(self.load, p["E_star"], p["R"]))
        return p

    def theta(self, p: dict) -> np.ndarray:
        return np.array([to_fitted(n, p[n]) for n in self.free])

    def model(self, p: dict) -> np.ndarray:
        with np.errstate(over="ignore", invalid="ignore"):  # trial points of the searches may overflow it
            values = expected_psd(self.omega_all, p, self.setting)  # (E*, q_min far out): the objective refuses
        return values.reshape(-1, self.bin_size).mean(axis=1)

    def objective(self, theta) -> float:
        """(log S + P/S) averaged over the bins, less a constant: -log L / (kappa n)."""
        S = self.model(self.params(theta))
        if not np.all(np.isfinite(S)) or np.any(S <= 0):
            return HUGE
        return float(np.mean(np.log(S) + self.data / S)) - self.offset

    def log_model_jacobian(self, theta) -> np.ndarray:
        """d log S_j / d theta_k (n, p) by central differences."""
        return log_jacobian(lambda t: self.model(self.params(t)), theta, 1e-5)


def log_jacobian(function, theta, step: float) -> np.ndarray:
    """d log f_j / d theta_k (n, p) of a positive ``function`` of theta returning n values, by
    central differences of step ``step * max(1, |theta_k|)``."""
    columns = []
    for k in range(len(theta)):
        h = step * max(1.0, abs(theta[k]))
        up, down = theta.copy(), theta.copy()
        up[k] += h
        down[k] -= h
        columns.append((np.log(function(up)) - np.log(function(down))) / (2 * h))
    return np.column_stack(columns)


def to_fitted(name: str, value: float) -> float:
    """A parameter's value in the fitted scale: its logarithm, or as is (``PARAMETERS[name][1]``)."""
    if PARAMETERS[name][1] != "log":
        return float(value)
    if not (math.isfinite(value) and value > 0):
        raise ParameterError(f"{name} = {value!r} is not allowed: it is fitted on a log scale and must be positive "
                             "and finite (a starting value from a spectrum without power, or one given so)")
    return math.log(value)


def from_fitted(name: str, value: float) -> float:
    """The inverse of :func:`to_fitted` (the exponent capped: no overflow at a search's far trials)."""
    return math.exp(min(value, 700.0)) if PARAMETERS[name][1] == "log" else float(value)


def goodness_of_fit(data, model, kappa: float, parameters: int) -> dict:
    """The module docstring's measures of ``data`` against ``model`` (n bins, ``parameters``
    fitted): bins, dof, deviance (also per dof, and its chi^2 p-value), phi, tau (and tau per
    block size) and the Kolmogorov-Smirnov p-value."""
    n = data.size
    z = math.sqrt(kappa) * (data / model - 1.0)
    phi = float(np.sum(z * z) / max(n - parameters, 1))
    tau, block_taus = long_run_factor(z)
    positive = data > 0
    ratio = data[positive] / model[positive]
    deviance = float(2.0 * kappa * np.sum(ratio - np.log(ratio) - 1.0))
    dof = max(n - parameters, 1)
    return {"bins": n, "dof": dof, "deviance": deviance, "deviance_per_dof": deviance / dof,
            "deviance_p": float(scipy.stats.chi2.sf(deviance, dof)), "phi": phi, "tau": tau,
            "tau_by_block": block_taus,
            "ks_p": float(scipy.stats.kstest(data / model, scipy.stats.gamma(kappa, scale=1.0 / kappa).cdf).pvalue)}


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
