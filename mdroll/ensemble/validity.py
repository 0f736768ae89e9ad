"""Where an ensemble leaves the model's range of validity: the checks behind the CLI's
``--force-physics`` and the ``physics_warnings`` of a run's summary.

Params only refuses what cannot be computed (omega_0 dt >= 2, a/dx < 10, ...). These checks
flag what can be computed but no longer means what the thesis's model says:

- a line RMS ``h_rms > MAX_H0_OVER_D0 d0`` (h0 for the ``"rms"`` level; for a spectrum of its own
  level, iso3095, bands or a table, the RMS of the generated lines,
  :func:`mdroll.roughness.line_grid.line_rms`, whatever h0 says): the MDR picture of physics.md (a Hertz contact at indentation d0
  with small height deviations, eq 14 and section 5.1) assumes h0 << d0; beyond it the wheel
  rides on asperities, the mean force leaves F_N (1.5 MN for F_N = 40 kN at h0 = 1 mm), and the
  decoupled mode's constant d = d0 is no longer the wheel's indentation.
- a resonance shift ``2 asin(omega_0 dt / 2) / (omega_0 dt) - 1`` (section 5,
  :func:`mdroll.physics.euler_resonance_phase`) above ``MAX_RESONANCE_SHIFT``: the time step
  no longer resolves the contact resonance, and near omega_0 dt = 2 the stiffer contact at
  peaks pushes the semi-implicit Euler step past its stability bound (an RMS force of
  8.4 MN at omega_0 dt = 1.99).
- contact lost (F = 0) on more than ``MAX_LOST_FRACTION`` of the steps: the spectra then hold
  the gaps of a wheel off the rail, not the linear response of section 5.1.
- bins where the estimator's leakage exceeds the signal (:mod:`mdroll.ensemble.resolution`) beyond
  ``MAX_UNRESOLVED_FRACTION`` of a spectrum: the leakage, not the physics, decides them (the
  lowest bins and the main lobe of omega_0, flagged in every record, are not counted).
"""

from __future__ import annotations

import math

import numpy as np

from .. import physics
from ..params import Params
from ..roughness.line_grid import from_params, line_rms, linear_force_psd
from .resolution import REASONS

#: The largest h0 / d0 taken as small roughness.
MAX_H0_OVER_D0 = 0.1
#: The largest relative shift of the contact resonance by the semi-implicit Euler step
#: (1 % at omega_0 dt = 0.49).
MAX_RESONANCE_SHIFT = 0.01
#: The largest fraction of the steps (over all realizations) with contact lost.
MAX_LOST_FRACTION = 0.01
#: The largest fraction of a spectrum's bins flagged unresolved without a warning.
MAX_UNRESOLVED_FRACTION = 0.01


def parameter_concerns(params: Params) -> list[str]:
    """Sentences naming each parameter that takes ``params`` out of the model's validity (empty
    when none does); see the module's docstring."""
    concerns = []
    if params.level == "rms":
        rms, name = params.h0, f"h0 = {params.h0!r} m"
    else:
        spectrum = from_params(params)
        rms = line_rms(params, spectrum)
        force = math.sqrt(2.0 * params.dq * float(np.sum(linear_force_psd(params, spectrum))))
        name = (f"the roughness line of roughness = {params.roughness!r} (its own level) has RMS {rms:.4g} m, a "
                f"dynamic force of {100 * force / params.F_N:.3g} % of F_N; it")
    if rms > MAX_H0_OVER_D0 * params.d0:
        concerns.append(
            f"{name} is {rms / params.d0:.3g} d0 (d0 = {params.d0:.4g} m): the model assumes "
            f"roughness small against the indentation (RMS <= {MAX_H0_OVER_D0} d0); the wheel rides on asperities "
            "and the mean force and spectra are not the thesis's"
        )
    omega_dt = params.omega_0 * params.dt
    shift = float(physics.euler_resonance_phase(params.omega_0, params.dt)) / omega_dt - 1.0
    if shift > MAX_RESONANCE_SHIFT:
        concerns.append(
            f"dx = {params.dx!r} m, v0 = {params.v0!r} m/s give omega_0 dt = {omega_dt:.4g} (dt = dx/v0): the time "
            f"step shifts the contact resonance by {100 * shift:.3g} % (at most {100 * MAX_RESONANCE_SHIFT:g} %) and "
            "nears the stability bound omega_0 dt < 2; lower dx or raise v0"
        )
    return concerns


def result_concerns(result) -> list[str]:
    """:func:`parameter_concerns` of a result's parameters, and the contact lost on more than
    ``MAX_LOST_FRACTION`` of its steps."""
    concerns = parameter_concerns(result.params)
    steps = result.n_real * result.steps
    if steps and result.contact_lost_steps > MAX_LOST_FRACTION * steps:
        concerns.append(
            f"contact was lost (F = 0) on {result.contact_lost_steps} of {steps} steps "
            f"({100 * result.contact_lost_steps / steps:.3g} %, more than {100 * MAX_LOST_FRACTION:g} %): the spectra "
            "hold a wheel leaving the rail, not the linear response of section 5.1; lower h0 or v0"
        )
    flags = result.resolution
    for quantity, name in (("accel", "acceleration"), ("force", "force")):
        mask = flags.reasons[quantity] == REASONS.index("leakage exceeds the signal")
        if mask.sum() > MAX_UNRESOLVED_FRACTION * mask.size:
            concerns.append(
                f"{int(mask.sum())} of {mask.size} {name} bins are unresolved ({100 * mask.mean():.3g} %: the "
                f"estimator's leakage exceeds the signal there{'' if result.window else ', as in any unwindowed open record'}); "
                "summary.json's resolution lists them, spectra.npz's "
                f"{quantity}_unresolved masks them" + ("" if result.window else "; the Hann window (the default) removes it")
            )
    return concerns
