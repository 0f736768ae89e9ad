"""Coupled wheel dynamics with the semi-implicit (symplectic) Euler step (physics.md section 5, eq 13).

Time is sequential per realization; one block per realization shares each step's spring sum.
The decoupled response (section 5.1) is linear and needs no time loop: kernels/spectra.py.
Semi-implicit Euler: ``v += dt a(y)`` first, then ``y += dt v`` with the new v; plain forward
Euler grows the oscillation energy by ~34 % over 10^6 steps at the defaults.
"""

import warp as wp

from .direct import force_direct
from .edge import edge_geometry, force_edge
from .tree import force_tree

DIRECT = wp.constant(0)
TREE = wp.constant(1)
EDGE = wp.constant(2)


#: Threads sharing one realization in the coupled dynamics on CUDA: one warp, so the per-step
#: block reduction needs no cross-warp synchronization. Warp runs tiles with one thread on the CPU.
COUPLED_LANES = 32


@wp.kernel
def coupled_response(
    algorithm: int,
    h: wp.array2d(dtype=wp.float64),
    prefix: wp.array2d(dtype=wp.float64),
    tree: wp.array2d(dtype=wp.vec2d),
    level_offsets: wp.array(dtype=int),
    bounds: wp.array(dtype=wp.vec2d),
    top_level: int,
    leaf_size: int,
    n: int,
    first: int,
    steps: int,
    d_start: wp.float64,
    dx: wp.float64,
    R: wp.float64,
    E_star: wp.float64,
    F_N: wp.float64,
    inv_mass: wp.float64,
    dt: wp.float64,
    force_offset: wp.float64,
    force: wp.array2d(dtype=wp.float64),
    accel: wp.array2d(dtype=wp.float64),
):
    """Eq 13: ``m d'' = F_N - F(x_w(t), d(t))``, d(0) = d_start (d0 in the thesis), d'(0) = 0, the wheel one spring per step.

    Launched tiled, one block per realization. Time is sequential, so the block shares each
    step's force instead: every lane sums its part of the springs (DIRECT: every lanes-th
    spring of the window; TREE: its slice of each band), a block-wide sum combines them, and
    every lane advances the same (d, d') with the same arithmetic. EDGE (eq 49 with
    a(d) = sqrt(d R) and the Hertz force at d) is O(1) per step and runs on lane 0. Writes
    ``force = F - force_offset`` (N) and ``accel = d''`` (m/s^2); steps without contact are
    those with F = 0.
    """
    r, lane = wp.tid()
    lanes = wp.block_dim()
    curvature = dx * dx / R
    k_spring = E_star * dx
    h_max = wp.float64(0.0)
    if algorithm == DIRECT:
        h_max = bounds[r][1]
    d = d_start
    v = wp.float64(0.0)
    for s in range(steps):
        c = first + s
        part = wp.float64(0.0)
        if algorithm == TREE:
            part = k_spring * force_tree(
                h, prefix, tree, level_offsets, top_level, leaf_size, r, n, c, d, curvature, lane, lanes
            )
        elif algorithm == DIRECT:
            part = k_spring * force_direct(h, r, n, c, d, h_max, curvature, lane, lanes)
        elif lane == 0 and d > wp.float64(0.0):
            part = force_edge(prefix, r, c, edge_geometry(d, dx, R, E_star))
        F = wp.tile_sum(wp.tile(part))[0]
        a = (F_N - F) * inv_mass
        if lane == 0:
            force[r, s] = F - force_offset
            accel[r, s] = a
        v += dt * a
        d += dt * v
