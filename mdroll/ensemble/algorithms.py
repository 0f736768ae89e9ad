"""The registry of contact-force algorithms: one :class:`Algorithm` entry per algorithm.

An entry says everything the rest of mdroll needs to know about an algorithm, so that no other
module branches on algorithm names:

- ``needs``: what :func:`~mdroll.ensemble.prepare.prepare_lines` must prepare for it (the row
  bounds, the prefix sums, the min/max tree) and whether its launch reads a lift table;
- ``force_launch``: its force launch, recorded (``wp.launch(..., record_cmd=True)``, or
  ``wp.launch_tiled``), from the prepared lines; :func:`~mdroll.ensemble.force.force_command`
  returns it;
- ``coupled``: its kernel of the coupled dynamics (eq 13) and that kernel's ``lines`` argument,
  or None where the algorithm has no coupled step (then ``mode="coupled"`` refuses it with a
  :class:`~mdroll.params.ParameterError`: there is no fallback);
- ``exact`` (equal to the direct sum to rounding) or an approximation, ``max_window`` (the
  contact window, springs a side, up to which its float64 closed forms are exact; None: no such
  limit), and its expected ``complexity`` for the scaling study (``mdroll bench``).

The kernels themselves live in one module per algorithm under ``mdroll/kernels``; the coupled
kernel of each is made there from its lane force by
:func:`mdroll.kernels.dynamics.coupled_dynamics`.

How to add an algorithm
-----------------------
1. Write ``mdroll/kernels/<name>.py`` (Warp only): the force kernel, launched over the
   (rows, steps) of a batch or blocks of them, writing ``force[r, s] = F - offset`` (N) with the
   wheel at spring ``first + s``; and, if it can take a step at a varying indentation, a lane
   force ``wp.func`` and ``coupled_<name> = coupled_dynamics(<its lines type>, <lane force>)``.
2. Add one entry to :data:`REGISTRY` below: its ``force_launch``, a function
   ``(prepared, params, d, offset, force, lifts, device) -> wp.Launch`` next to the others
   here (or in a host module of its own, as ``ensemble/sweep.py``) that reads the
   :class:`~mdroll.ensemble.prepare.PreparedLines` fields it needs and records the launch that
   writes ``force`` (``lifts``: the lift table and its origin when it needs one, else None);
   ``needs``, ``coupled`` (or None), ``exact``, ``max_window`` and ``complexity``.

The CLI's ``--algorithm`` choices, :data:`mdroll.ALGORITHMS`, the pipeline, the coupled
dynamics and the scaling study pick it up from there; the tests that compare every exact
algorithm with the direct sum (tests/test_force.py) run it too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

from ..kernels.common import BLOCK, MAX_CLOSED_FORM_OFFSET, Contact
from ..kernels.direct import DirectLines, contact_force_direct, coupled_direct
from ..kernels.edge import EdgeGeometry, contact_force_edge, coupled_edge
from ..kernels.tree import TreeLines, contact_force_tree, coupled_tree
from .. import physics
from ..devices import warp
from ..params import ParameterError, Params
from .sweep import sweep_coupled, sweep_launch

#: Prepared data an algorithm may need (the values of :attr:`Algorithm.needs`).
BOUNDS = "row bounds"  # (min h, max h) of each row, and the largest height of the batch
PREFIX = "prefix sums"  # S_j = sum_{i<j} h_i per row (eq 18)
TREE = "min/max tree"  # the implicit (min h, max h) tree per row (kernels/tree.py)
LIFTS = "lift table"  # the indenter's profile d - curvature m^2 over the window, per launch


@dataclass(frozen=True)
class Complexity:
    """Expected growth of the force time with n (``time ~ n^p``): under ``refinement`` (fixed L,
    dx halving; None where no single exponent fits, with the reason in ``note``) and over
    rolling ``distance`` (fixed dx); ``text`` says it in words (the CLI's help)."""

    refinement: float | None
    distance: float = 1.0
    text: str = ""
    note: str = ""


@dataclass(frozen=True)
class BenchVariant:
    """A setting of an algorithm that the scaling study times beside its default: ``options``
    go to :func:`~mdroll.ensemble.prepare.prepare_lines`; ``refinement`` as in :class:`Complexity`."""

    name: str
    options: dict
    refinement: float


@dataclass(frozen=True)
class Algorithm:
    """One force algorithm.

    Attributes
    ----------
    name, description : str
        Its name (``algorithm=`` everywhere) and what it computes, in a phrase.
    exact : bool
        Whether it gives the direct sum (eq 10-12) to rounding; else an approximation.
    needs : frozenset
        What :func:`~mdroll.ensemble.prepare.prepare_lines` prepares for it (:data:`BOUNDS`,
        :data:`PREFIX`, :data:`TREE`) and whether its launch reads a :data:`LIFTS` table.
    force_launch : callable
        ``(prepared, params, d, offset, force, lifts, device) -> wp.Launch``: the recorded
        launch that writes ``force[r, s] = F - offset`` (N) at indentation d (m).
    coupled : callable or None
        ``(prepared) -> (kernel, lines)``: its eq 13 kernel
        (:func:`~mdroll.kernels.dynamics.coupled_dynamics`) and that kernel's ``lines``
        argument; None: no coupled step (``mode="coupled"`` refuses the algorithm).
    complexity : Complexity
        Expected scaling, for ``mdroll bench``'s fits and the CLI's help.
    max_window : int or None
        Contact windows (springs a side) up to which its float64 closed forms are exact; a
        wider one is refused before launch. None: no such limit.
    bench_variants : tuple of BenchVariant
        Settings the scaling study times beside the default.
    bench_point_limit : dict
        The scaling study's largest problem (realizations x points) per device kind ("cpu",
        "cuda") in a full study; no entry: no limit.
    """

    name: str
    description: str
    exact: bool
    needs: frozenset
    force_launch: Callable
    coupled: Callable | None
    complexity: Complexity
    max_window: int | None = None
    bench_variants: tuple = ()
    bench_point_limit: dict = field(default_factory=dict)


def indenter_curvature(params: Params) -> float:
    """``g(dx) = dx^2 / R`` (m, eq 7): the MDR indenter lowers the spring m places from the
    wheel by ``curvature m^2``."""
    return physics.indenter_profile(params.dx, params.R)


def contact_constants(params: Params) -> Contact:
    """The :class:`~mdroll.kernels.common.Contact` of ``params``: dx, R, E*, the indenter's
    curvature (:func:`indenter_curvature`) and the spring stiffness ``E* dx`` (N/m, eq 11-12)."""
    contact = Contact()
    contact.dx, contact.R, contact.E_star = params.dx, params.R, params.E_star
    contact.curvature = indenter_curvature(params)
    contact.k_spring = params.k_spring
    return contact


def edge_geometry(params: Params, d: float) -> EdgeGeometry:
    """The :class:`~mdroll.kernels.edge.EdgeGeometry` of eq 49 at indentation d (m), from the
    closed forms of :mod:`mdroll.physics` (the kernel's :func:`~mdroll.kernels.edge.edge_geometry`
    computes the same, in the same order, per step of the coupled dynamics)."""
    a = physics.contact_radius(d, params.R)
    alpha = a / params.dx
    geometry = EdgeGeometry()
    geometry.whole = int(math.floor(alpha))
    geometry.fraction = alpha - geometry.whole
    geometry.hertz = physics.hertz_force(d, params.E_star, params.R)
    geometry.tip = physics.edge_coefficient(params.E_star, params.R, a)
    geometry.dx_E_star = physics.spring_stiffness(params.E_star, params.dx)
    return geometry


def _blocked_launch(kernel, inputs, force, device):
    """The recorded launch of a kernel whose threads compute BLOCK consecutive steps of a row."""
    dim = (force.shape[0], -(-force.shape[1] // BLOCK))
    return warp().launch(kernel, dim=dim, inputs=inputs, device=device, record_cmd=True)


def _direct_launch(p, params: Params, d: float, offset: float, force, lifts, device):
    table, origin = lifts
    inputs = [p.lines, p.bounds, table, origin, p.n_work, p.first, p.steps, d, indenter_curvature(params),
              params.k_spring, offset, force]
    return _blocked_launch(contact_force_direct, inputs, force, device)


def _direct_coupled(p):
    lines = DirectLines()
    lines.h, lines.bounds, lines.n = p.lines, p.bounds, p.n_work
    return coupled_direct, lines


def tree_lines(p) -> TreeLines:
    """The :class:`~mdroll.kernels.tree.TreeLines` of prepared lines ``p``."""
    lines = TreeLines()
    lines.h, lines.prefix, lines.nodes, lines.level_offsets = p.lines, p.prefix, p.tree, p.level_offsets
    lines.top_level, lines.leaf_size, lines.band_limit, lines.n = p.top_level, p.leaf_size, p.band_limit, p.n_work
    return lines


def _tree_launch(p, params: Params, d: float, offset: float, force, lifts, device):
    table, origin = lifts
    inputs = [tree_lines(p), table, origin, p.first, p.steps, d, indenter_curvature(params), params.k_spring, offset,
              force]
    return _blocked_launch(contact_force_tree, inputs, force, device)


def _tree_coupled(p):
    return coupled_tree, tree_lines(p)


def _edge_launch(p, params: Params, d: float, offset: float, force, lifts, device):
    return warp().launch(contact_force_edge, dim=force.shape, inputs=[p.prefix, p.first, edge_geometry(params, d),
                                                                      offset, force], device=device, record_cmd=True)


def _edge_coupled(p):
    return coupled_edge, p.prefix


#: Every algorithm by name.
REGISTRY: dict[str, Algorithm] = {
    a.name: a
    for a in (
        Algorithm(
            name="tree",
            description="the bounding-tree algorithm, equal to direct to rounding",
            exact=True,
            needs=frozenset({BOUNDS, PREFIX, TREE, LIFTS}),
            force_launch=_tree_launch,
            coupled=_tree_coupled,
            max_window=MAX_CLOSED_FORM_OFFSET,
            complexity=Complexity(
                refinement=None, text="O(n log n) a line under refinement",
                note="hybrid: bands up to band_limit springs summed directly; n log n: tree-descent"),
            # every band traversed (band_limit 0): the O(n log n) traversal of physics.md
            # section 4 at every size, next to the default, which sums the narrowed bands
            # directly up to DEFAULT_BAND_LIMIT springs and traverses wider ones
            bench_variants=(BenchVariant("tree-descent", {"band_limit": 0}, refinement=1.1),),
            bench_point_limit={"cpu": 2**22},
        ),
        Algorithm(
            name="direct",
            description="the exact spring sum (eq 10-12) over the window of possible contact",
            exact=True,
            needs=frozenset({BOUNDS, LIFTS}),
            force_launch=_direct_launch,
            coupled=_direct_coupled,
            max_window=MAX_CLOSED_FORM_OFFSET,
            complexity=Complexity(refinement=2.0, text="O(n^2) a line under refinement"),
            # one CPU core takes ~1 us a step; on the GPU 2^26 points at 2^20 a line is ~1 s
            bench_point_limit={"cpu": 2**20, "cuda": 2**26},
        ),
        Algorithm(
            name="edge",
            description="the edge-incremental approximation of eq 49",
            exact=False,
            needs=frozenset({PREFIX}),
            force_launch=_edge_launch,
            coupled=_edge_coupled,
            complexity=Complexity(refinement=1.0, text="O(n) a line"),
            bench_point_limit={"cpu": 2**23},
        ),
        Algorithm(
            name="sweep",
            description="exact in O(n) at fixed d: running totals over the springs in contact, equal to direct to "
                        "rounding (coupled: the core in closed form and the bands spring by spring)",
            exact=True,
            # the row bounds only: its CUDA stream sums each segment's anchor spring by spring;
            # the forms and the coupled step that read prefix sums build them on first use
            # (ensemble/sweep.py), so that the CUDA build is the bounds pass alone
            needs=frozenset({BOUNDS}),
            force_launch=sweep_launch,
            # d varies every step of the coupled dynamics, so no totals carry over there: its
            # step sums the bands directly (O(band) a step; DEFAULT_ALGORITHMS has the measurement)
            coupled=sweep_coupled,
            max_window=MAX_CLOSED_FORM_OFFSET,  # the tile's core closed form, sum of m^2
            complexity=Complexity(refinement=1.0, text="O(n) a line"),
            bench_point_limit={"cpu": 2**23},
        ),
    )
}

#: The algorithms' names.
ALGORITHMS = tuple(REGISTRY)
#: The algorithm each mode takes by default (:func:`mdroll.contact_force`, whose indentation is
#: fixed, takes the decoupled one; :func:`mdroll.run_ensemble`, :class:`mdroll.EnsembleSpec` and
#: the CLI take their mode's): the fastest exact one there. The sweep is exact and O(n) at fixed d
#: (CPU, 2^20 springs at the defaults: ~30 ns a step against ~190 for the tree). In the coupled
#: dynamics its step sums the bands directly, O(band) a step: 1.33 s against the tree's 3.64 at
#: thesis scale on an H200, and faster than the tree down to dx = 0.31 um (band ~700 springs a
#: side; docs/performance.md), below which the tree's descent wins.
DEFAULT_ALGORITHMS = {"decoupled": "sweep", "coupled": "sweep"}


def default_algorithm(mode: str = "decoupled") -> str:
    """The registry's default algorithm of ``mode`` ("decoupled" or "coupled")."""
    if mode not in DEFAULT_ALGORITHMS:
        raise ParameterError(f"mode = {mode!r} is not allowed: choose one of {', '.join(DEFAULT_ALGORITHMS)}")
    return DEFAULT_ALGORITHMS[mode]


def algorithm_entry(name) -> Algorithm:
    """The registry entry of ``name``, or a ParameterError naming the choices."""
    if name not in REGISTRY:
        raise ParameterError(f"algorithm = {name!r} is not allowed: choose one of {', '.join(ALGORITHMS)}")
    return REGISTRY[name]


def coupled_entry(name) -> Algorithm:
    """The registry entry of ``name`` for the coupled dynamics, or a ParameterError when the
    algorithm has no coupled step (naming those that have one)."""
    entry = algorithm_entry(name)
    if entry.coupled is None:
        usable = ", ".join(a.name for a in REGISTRY.values() if a.coupled is not None)
        raise ParameterError(f"algorithm = {name!r} has no coupled step: mode = 'coupled' takes one of {usable}")
    return entry
