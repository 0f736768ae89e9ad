r"""
Comparing the force algorithms
==============================

The contact force along one rough line by the three algorithms of
:func:`mdroll.contact_force` (:doc:`theory, section 4 </physics>`): the direct sum over every
spring that can touch (the exact reference), the bounding tree (exact, :math:`O(n \log n)`)
and the edge-incremental approximation of eq 49 (:math:`O(n)`). The tree equals the direct sum to
floating-point rounding; edge follows the force closely but adds high-frequency content at the
contact edges.
"""

import matplotlib.pyplot as plt
import numpy as np

import mdroll

params = mdroll.Params(L=0.1)  # 20,000 springs of 5 µm, thesis defaults otherwise
lines = mdroll.rough_lines(params, seed=3, realizations=1)  # (1, n), metres
forces = {algorithm: mdroll.contact_force(lines, params, algorithm=algorithm, boundary="periodic")[0]
          for algorithm in ("direct", "tree", "edge")}  # newtons, one per wheel position

x = np.arange(params.n_points) * params.dx  # wheel positions x_w (m), periodic: every spring
tree_error = np.max(np.abs(forces["tree"] - forces["direct"])) / params.F_N
edge_rms = np.sqrt(np.mean((forces["edge"] - forces["direct"]) ** 2))
print(f"max |tree - direct| = {tree_error:.2g} F_N; RMS edge - direct = {edge_rms:.3g} N")

fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), dpi=100, sharex=True)
window = x < 0.02
for name, style in (("direct", "-"), ("tree", "--"), ("edge", ":")):
    top.plot(x[window] * 1e3, forces[name][window] - params.F_N, style, lw=1, label=name)
top.set_ylabel("F - F_N (N)")
top.legend(loc="upper right")
top.set_title("contact force along a rough line, H = 0.7, h0 = 0.5 µm")
bottom.plot(x[window] * 1e3, (forces["edge"] - forces["direct"])[window], color="C2", lw=0.8,
            label="edge - direct")
bottom.plot(x[window] * 1e3, (forces["tree"] - forces["direct"])[window], color="C1", lw=0.8,
            label="tree - direct")
bottom.set_xlabel("wheel position x_w (mm)")
bottom.set_ylabel("difference (N)")
bottom.legend(loc="upper right")
fig.tight_layout()
plt.show()
