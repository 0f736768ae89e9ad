r"""
The thesis's acceleration spectrum
==================================

The wheel's normal acceleration spectrum at the thesis's parameters (:math:`\Delta x` = 5 µm,
:math:`H` = 0.7, :math:`h_0` = 0.5 µm, open boundary, decoupled dynamics, the default exact
algorithm), on a 1 m line with 24 realizations instead of 5 m and 300, so that it runs in seconds
on one CPU core.

The figure shows the features of the thesis's Figure 2: the contact resonance at
:math:`\omega_0 = \sqrt{2 a E^*/m}`, the onset of the roughness band at :math:`q_{min} v_0`
(eq 21), the power-law fall :math:`q^{-(2H+3)}` (eq 23) with its modulation of period
:math:`\pi v_0/a` (eq 26), and eq 40 carried through the wheel's linearized response. The
shaded band is the ensemble's standard error.
"""

import matplotlib.pyplot as plt

import mdroll
from mdroll.plotting import plot_psd

params = mdroll.Params(L=1.0)  # every other parameter at the thesis default, SI units
print(f"E* = {params.E_star:.4g} Pa, a = {params.a * 1e3:.4g} mm, omega_0 = {params.omega_0:.1f} rad/s")
result = mdroll.run_ensemble(params, seed=1, realizations=24, device="cpu", progress=False)

fig, ax = plt.subplots(figsize=(8, 5), dpi=100)
plot_psd(result, "accel", ax=ax)
ax.set_ylim(1e-12, None)
fig.tight_layout()
plt.show()

# %%
# The spectrum is per rad/s, two-sided: :math:`C(\omega) = C(q)/v_0` at :math:`\omega = q v_0`
# (:doc:`theory, section 6 </physics>`). The arrays are on the result (:class:`mdroll.EnsembleResult`),
# with the standard error of every bin:
print(f"{result.n_real} realizations, {result.steps} steps of dt = {params.dt:.3g} s each")
print(f"q from {result.q[1]:.3g} to {result.q[-1]:.3g} rad/m; force mean {result.force_mean:.6g} N")
