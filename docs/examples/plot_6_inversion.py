r"""
The inverse problem: parameters from an acceleration spectrum
=============================================================

:func:`mdroll.inverse.fit` estimates the roughness and contact parameters (:math:`H`,
:math:`q_{min}`, the contact radius :math:`a`, :math:`h_0`, :math:`E^*`) from an averaged
acceleration spectrum by the Whittle likelihood, with eq 40 through the wheel's response as
the forward model (:doc:`theory, sections 5.1 and 7 </physics>`). Here the "measurement" is a
small simulated ensemble (Hann-windowed, as a measured series would be), so the truth is known;
the wheel's mass and radius are taken as known. With 8 short lines the intervals are narrow
and calibrated on average only: at this size an estimate may miss its truth by a little more
than its interval (here :math:`E^*`, which the data see only through the resonance's tail).
``mdroll invert spectra.npz`` does the same from the command line, and ``mdroll invert`` reads
measured spectra from tables too.
"""

import matplotlib.pyplot as plt

import mdroll
from mdroll.inverse import fit, from_result

truth = mdroll.Params(L=0.3)
result = mdroll.run_ensemble(truth, seed=4, realizations=8, window=True, device="cpu", progress=False)
spectrum = from_result(result, "accel", window=True)  # two-sided per rad/s on omega = q v0
estimate = fit(spectrum, known={"m": truth.m, "R": truth.R}, profile=False)

print(f"{'parameter':9s} {'truth':>11s} {'estimate':>11s}   95 % interval")
for name in estimate.free:
    lo, hi = estimate.ci95[name]
    true_value = estimate.truth.get(name, float("nan")) if estimate.truth else float("nan")
    print(f"{name:9s} {true_value:11.4g} {estimate.estimates[name]:11.4g}   [{lo:.4g}, {hi:.4g}]")

# %%
# The fitted model over the data, on the band the fit used.

fig, ax = plt.subplots(figsize=(8, 5), dpi=100)
ax.loglog(estimate.omega, estimate.data, lw=0.6, label=f"simulated ensemble ({result.n_real} lines, Hann window)")
ax.loglog(estimate.omega, estimate.model, lw=1.0, color="C3", label="fitted model")
ax.set_xlabel(r"$\omega$ (rad/s)")
ax.set_ylabel(r"acceleration PSD $C(\omega)$ ((m/s$^2$)$^2$ s/rad)")
ax.set_title(f"Whittle fit on {estimate.band[0]:.3g} .. {estimate.band[1]:.3g} rad/s")
ax.legend(loc="lower left")
fig.tight_layout()
plt.show()
