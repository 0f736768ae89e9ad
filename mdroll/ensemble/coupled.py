"""Driving the coupled wheel dynamics (eq 13) over prepared lines: the series of force and acceleration."""

from __future__ import annotations

from ..devices import warp
from ..params import Params


def coupled_series(prepared, params: Params, algorithm: str, device: str, d_start: float | None = None,
                   force_offset: float = 0.0):
    """Force (N, less ``force_offset``) and acceleration d'' (m/s^2) series of eq 13 for
    prepared lines; the wheel starts at indentation ``d_start`` (default d0) at rest. Contact is
    lost where F = 0."""
    from ..kernels.dynamics import COUPLED_LANES, DIRECT, EDGE, TREE, coupled_response

    wp = warp()
    rows = prepared.lines.shape[0]
    force = wp.empty((rows, prepared.steps), dtype=wp.float64, device=device)
    accel = wp.empty_like(force)
    empty_tree = wp.empty((rows, 1), dtype=wp.vec2d, device=device)
    empty_prefix = wp.empty((rows, 1), dtype=wp.float64, device=device)
    code = {"direct": DIRECT, "tree": TREE, "edge": EDGE}[algorithm]
    wp.launch_tiled(
        coupled_response,
        dim=[rows],
        block_dim=COUPLED_LANES,
        inputs=[code, prepared.lines,
                prepared.prefix if prepared.prefix is not None else empty_prefix,
                prepared.tree if prepared.tree is not None else empty_tree,
                prepared.level_offsets if prepared.level_offsets is not None else wp.zeros(1, dtype=wp.int32, device=device),
                prepared.bounds if prepared.bounds is not None else wp.empty(1, dtype=wp.vec2d, device=device),
                prepared.top_level, prepared.leaf_size, prepared.n_work, prepared.first, prepared.steps,
                params.d0 if d_start is None else d_start, params.dx, params.R, params.E_star, params.F_N, 1.0 / params.m, params.dt, force_offset, force, accel],
        device=device,
    )
    return force, accel
