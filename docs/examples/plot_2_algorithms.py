r"""
Comparing the force algorithms
==============================

The contact force along one rough line by every algorithm of :func:`mdroll.contact_force`
(``mdroll.ALGORITHMS``; :doc:`theory, section 4 </physics>`): among them the direct sum over every
spring that can touch (the exact reference), the bounding tree (exact, :math:`O(n \log n)`) and
the edge-incremental approximation of eq 49 (:math:`O(n)`). The exact algorithms equal the direct
sum to floating-point rounding; edge follows the force closely but adds high-frequency content
at the contact edges.
"""

import matplotlib.pyplot as plt
import numpy as np

import mdroll

params = mdroll.Params(L=0.1)  # 20,000 springs of 5 µm, thesis defaults otherwise
lines = mdroll.rough_lines(params, seed=3, realizations=1)  # (1, n), metres
forces = {algorithm: mdroll.contact_force(lines, params, algorithm=algorithm, boundary="periodic")[0]
          for algorithm in mdroll.ALGORITHMS}  # newtons, one per wheel position
for algorithm, force in forces.items():
    difference = force - forces["direct"]
    print(f"{algorithm:7s} max |F - F_direct| = {np.max(np.abs(difference)) / params.F_N:.2g} F_N, "
          f"RMS {np.sqrt(np.mean(difference**2)):.3g} N")

# %%
# The first 20 mm of the line: the forces, then each algorithm's difference to the direct sum.

x = np.arange(params.n_points) * params.dx  # wheel positions x_w (m), periodic: every spring
window = x < 0.02
fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), dpi=100, sharex=True)
for (algorithm, force), style in zip(forces.items(), ("-", "--", ":", "-.")):
    top.plot(x[window] * 1e3, force[window] - params.F_N, style, lw=1, label=algorithm)
    if algorithm != "direct":
        bottom.plot(x[window] * 1e3, (force - forces["direct"])[window], lw=0.8, label=f"{algorithm} - direct")
top.set_ylabel("$F - F_N$ (N)")
top.legend(loc="upper right")
top.set_title("contact force along a rough line, H = 0.7, h0 = 0.5 µm")
bottom.set_xlabel("wheel position $x_w$ (mm)")
bottom.set_ylabel("difference (N)")
bottom.legend(loc="upper right")
fig.tight_layout()
plt.show()
