"""The gate a fit passes before its estimates are reported as the spectrum's parameters.

A fit is *rejected* (``accepted = False``, with the reasons) when

- **the model misses structure over many bins**: the residuals' long-run factor at the largest
  block size B of :func:`~mdroll.inverse.likelihood.long_run_factor` (``nb >= 16`` blocks) is
  tested against the estimator's own, :data:`OWN_TAU` (1 without a window; 1.94 with the Hann
  window, whose neighbouring bins correlate): under the model the batch-means estimate scales as
  ``tau_B / tau_own ~ chi^2_(nb-1) / (nb - 1)``, and the fit is rejected when that has a p-value
  below :data:`LEVEL`. This is the smooth part of the deviance; the deviance's chi-square test and
  the Kolmogorov-Smirnov test of P/S against Gamma(kappa) are reported but not gated on, since
  mdroll's spectra are not chi-square per bin (fixed amplitudes, random phases: dispersion phi <
  1), so both reject well-fitted spectra too (docs/inverse.md, "The acceptance gate");
- **more than :data:`MAX_UNRESOLVED` of the band's bins are unresolved** by the record
  (:mod:`mdroll.ensemble.resolution`): the estimator's leakage, not the physics, decides them.

An unwindowed mdroll spectrum is named in the notes: its leakage alone usually fails both.
"""

from __future__ import annotations

import math

import scipy.stats

#: The significance level at which the gate rejects the model.
LEVEL = 1e-3
#: The long-run factor of the residuals of a correct model, per estimator (window or not).
OWN_TAU = {False: 1.0, True: 1.94}
#: The largest fraction of the band's bins that may be unresolved.
MAX_UNRESOLVED = 0.05


def acceptance(gof: dict, band: tuple, spectrum, discrepancy: dict | None = None) -> dict:
    """The gate of the module docstring for a fit with goodness of fit ``gof``
    (:func:`~mdroll.inverse.likelihood.goodness_of_fit`) over ``band`` (rad/s) of ``spectrum``:
    ``{"accepted", "level", "reasons", "notes", "misfit_p", "unresolved_in_band"}``. With a model
    ``discrepancy`` held (:mod:`.discrepancy`, a table's fit) a smooth misfit is what it allows
    for: the block test is then a note, not a reason."""
    reasons, notes = [], []
    taus = {int(k): v for k, v in gof.get("tau_by_block", {}).items()}
    misfit_p = None
    if len(gof.get("tau_by_block", {})) > 1:
        block = max(taus)
        blocks = gof["bins"] // block
        own = OWN_TAU[bool(spectrum.window)]
        statistic = (blocks - 1) * taus[block] / own
        misfit_p = float(scipy.stats.chi2.sf(statistic, blocks - 1))
        if misfit_p < LEVEL:
            (notes if discrepancy else reasons).append(f"the model misses structure over many bins: the residuals' means over {block} bins vary "
                           f"{taus[block] / own:.3g}x what the estimator allows (p = {misfit_p:.2g} < {LEVEL:g})")
    unresolved = {"bins": 0, "of_bins": 0}
    if spectrum.unresolved is not None:
        inside = (spectrum.omega >= band[0]) & (spectrum.omega <= band[1])
        flagged = inside & spectrum.unresolved
        unresolved = {"bins": int(flagged.sum()), "of_bins": int(inside.sum())}
        if flagged.any():
            unresolved["omega_rad_s"] = [float(spectrum.omega[flagged].min()), float(spectrum.omega[flagged].max())]
            share = flagged.sum() / max(inside.sum(), 1)
            text = (f"{int(flagged.sum())} of the band's {int(inside.sum())} bins (between {unresolved['omega_rad_s'][0]:.4g} "
                    f"and {unresolved['omega_rad_s'][1]:.4g} rad/s) are unresolved by the record")
            (reasons if share > MAX_UNRESOLVED else notes).append(text + (f" (more than {100 * MAX_UNRESOLVED:g} %)"
                                                                          if share > MAX_UNRESOLVED else ""))
    if spectrum.simulation and not spectrum.window:
        notes.append("the spectrum is from an unwindowed run (the thesis's estimator): its leakage fills the band's "
                     "notches and the resonance's flanks; a default (Hann-windowed) run avoids it")
    if not math.isfinite(gof.get("deviance", math.nan)):
        reasons.append("the deviance is not finite")
    return {"accepted": not reasons, "level": LEVEL, "reasons": reasons, "notes": notes, "misfit_p": misfit_p,
            "unresolved_in_band": unresolved}

