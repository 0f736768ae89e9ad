r"""
A validation check: eq 40 against an ensemble
=============================================

Above the long-wave cutoff :math:`q_{min}` the contact force follows the roughness linearly,
and its PSD is eq 40 of the thesis (:doc:`theory, section 7 </physics>`):

.. math::

    C_F(q) = \lambda A \left(\frac{2 E^*}{q}\right)^2 q^{-2H-1} \sin^2(q a) .

This example averages the force PSD of 32 periodic lines (the wheel rolls the whole line, so
there is no leakage), averages both curves over whole modulation periods (:math:`\pi/a`, eq 26)
and compares them band by band, as ``mdroll validate`` does at larger sizes
(:func:`mdroll.physics.force_psd_high_band` is eq 40).
"""

import matplotlib.pyplot as plt
import numpy as np

import mdroll
from mdroll import physics

params = mdroll.Params(L=0.5, dx=10e-6)  # 10 µm springs: ~1000 per contact diameter
result = mdroll.run_ensemble(params, seed=2, realizations=32, boundary="periodic", device="cpu",
                             progress=False)
q, measured = result.q, result.force_psd  # rad/m, N^2 m (two-sided, per rad/m)
predicted = physics.force_psd_high_band(q, params.lambda_A, params.H, params.q_min, params.q_max,
                                        params.E_star, params.a)

# %%
# Band averages over whole modulation periods remove the sin^2(q a) zeros, which would make a
# bin-by-bin ratio meaningless.

# whole modulation periods pi/a from q_min up to 16 q_min
period = np.pi / params.a
edges = np.arange(params.q_min, 16 * params.q_min, period)
centres, ratios = [], []
for lo, hi in zip(edges[:-1], edges[1:]):
    band = (q >= lo) & (q < hi)
    centres.append(q[band].mean())
    ratios.append(measured[band].mean() / predicted[band].mean())
ratios = np.array(ratios)
print(f"measured / eq 40 over {len(ratios)} periods: mean {ratios.mean():.3f}, "
      f"range {ratios.min():.3f} .. {ratios.max():.3f}")

fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), dpi=100, sharex=True,
                                  gridspec_kw={"height_ratios": [2, 1]})
inside = (q > 0.5 * params.q_min) & (q < 16 * params.q_min)
top.loglog(q[inside], measured[inside], lw=0.6, label=f"ensemble mean ({result.n_real} lines)")
positive = inside & (predicted > 0)
top.loglog(q[positive], predicted[positive], lw=0.6, color="C3", label="eq 40")
top.axvline(params.q_min, color="0.4", ls=":", lw=0.8)
top.set_ylabel("C_F(q) (N$^2$ m)")
top.legend(loc="lower left")
bottom.semilogx(centres, ratios, "o-", ms=3)
bottom.axhline(1.0, color="k", lw=0.6)
bottom.set_ylim(0.7, 1.3)
bottom.set_xlabel("q (rad/m)")
bottom.set_ylabel("measured / eq 40")
fig.tight_layout()
plt.show()
