r"""
A sweep of ensembles, on a Dask cluster when there is one
=========================================================

:func:`mdroll.run_specs` runs a list of ensembles (:class:`mdroll.EnsembleSpec`: parameters,
seed, realizations, algorithm, mode, boundary). Given a ``runner`` from :mod:`mdroll.distributed`
it spreads their realizations over the workers of a Dask cluster, and the merged spectra equal a
one-process run to rounding (see :doc:`/distributed`).

Here four ensembles differ in the Hurst exponent :math:`H`. Set ``MDROLL_SCHEDULER`` to a
scheduler's address (``tcp://host:8786``) to run them on that cluster; without one, as when this
page is built, the same call runs them in this process.
"""

import os

import matplotlib.pyplot as plt
import numpy as np

import mdroll

specs = [mdroll.EnsembleSpec(mdroll.Params(L=0.5, dx=10e-6, H=H), seed=5, realizations=8, boundary="periodic")
         for H in (0.3, 0.5, 0.7, 0.9)]

scheduler = os.environ.get("MDROLL_SCHEDULER")
if scheduler:
    from mdroll.distributed import DaskRunner, connect

    with connect(scheduler=scheduler) as client:
        results = mdroll.run_specs(specs, runner=DaskRunner(client))
else:
    results = mdroll.run_specs(specs, device="cpu")

# %%
# The four spectra, and the same spectra compensated by eq 23: flat peaks mean the slope is
# 2H + 3 at every H.

fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 7), dpi=100)
for spec, result in zip(specs, results):
    p, q = spec.params, result.q
    top.loglog(q[1:], result.force_psd[1:], lw=0.6, label=f"H = {p.H}")
    # eq 23: above q_min the envelope falls as q^-(2H+3), so the compensated PSD's peaks are flat
    band = (q > p.q_min) & (q < 12 * p.q_min)
    compensated = result.force_psd[band] * (q[band] / p.q_min) ** (2 * p.H + 3)
    bottom.plot(q[band] / p.q_min, compensated / compensated.max(), lw=0.8)
top.axvline(specs[0].params.q_min, color="0.5", lw=0.6)
top.set_ylabel("force PSD $C_F(q)$ (N$^2$ m)")
top.set_title(f"{len(specs)} ensembles of {specs[0].realizations} periodic lines")
top.legend(loc="lower left")
bottom.set_xlabel("$q / q_{min}$")
bottom.set_ylabel("$C_F \\, (q/q_{min})^{2H+3}$, scaled")
bottom.set_title("compensated by eq 23: flat peaks")
fig.tight_layout()
plt.show()
