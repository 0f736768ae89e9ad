"""Host side of the bounding-tree algorithm (:mod:`mdroll.kernels.tree`): its force launch and its
coupled step, for the registry (:mod:`mdroll.forces.registry`)."""

from __future__ import annotations

from ..kernels.tree import TreeLines, contact_force_tree, coupled_tree
from ..params import Params
from .blocked import blocked_launch
from .indenter import indenter_curvature


def tree_lines(p) -> TreeLines:
    """The :class:`~mdroll.kernels.tree.TreeLines` of prepared lines ``p``."""
    lines = TreeLines()
    lines.h, lines.prefix, lines.nodes, lines.level_offsets = p.lines, p.prefix, p.tree, p.level_offsets
    lines.top_level, lines.leaf_size, lines.band_limit, lines.n = p.top_level, p.leaf_size, p.band_limit, p.n_work
    return lines


def tree_launch(p, params: Params, d: float, offset: float, force, lifts, device):
    """The registry's ``force_launch`` of the tree: reads the tree, the prefix sums and the lift table."""
    table, origin = lifts
    inputs = [tree_lines(p), table, origin, p.first, p.steps, d, indenter_curvature(params), params.k_spring, offset,
              force]
    return blocked_launch(contact_force_tree, inputs, force, device)


def tree_coupled(p):
    """The registry's ``coupled`` of the tree: its eq 13 kernel and :class:`TreeLines`."""
    return coupled_tree, tree_lines(p)
