"""The registry of contact-force algorithms: one :class:`~mdroll.forces.algorithm.Algorithm`
entry per algorithm.

An entry says everything the rest of mdroll needs to know about an algorithm, so that no other
module branches on algorithm names:

- ``needs``: what :func:`~mdroll.forces.prepare.prepare_lines` must prepare for it (the row
  bounds, the prefix sums, the min/max tree) and whether its launch reads a lift table;
- ``force_launch``: its force launch, recorded (``wp.launch(..., record_cmd=True)``, or
  ``wp.launch_tiled``), from the prepared lines; :func:`~mdroll.forces.force.force_command`
  returns it;
- ``coupled``: its kernel of the coupled dynamics (eq 13) and that kernel's ``lines`` argument,
  or None where the algorithm has no coupled step (then ``mode="coupled"`` refuses it with a
  :class:`~mdroll.errors.ParameterError`: there is no fallback);
- ``exact`` (equal to the direct sum to rounding) or an approximation, ``max_window`` (the
  contact window, springs a side, up to which its float64 closed forms are exact; None: no such
  limit), and its expected ``complexity`` for the scaling study (``mdroll bench``).

The kernels live in one module per algorithm under ``mdroll/kernels``, their host side (the
launch and the coupled step's arguments) in the module of the same name under
``mdroll/forces``; the coupled kernel of each is made from its lane force by
:func:`mdroll.kernels.dynamics.coupled_dynamics`. The registry imports the launchers, never the
other way round.

How to add an algorithm
-----------------------
1. Write ``mdroll/kernels/<name>.py`` (Warp only): the force kernel, launched over the
   (rows, steps) of a batch or blocks of them, writing ``force[r, s] = F - offset`` (N) with the
   wheel at spring ``first + s``; and, if it can take a step at a varying indentation, a lane
   force ``wp.func`` and ``coupled_<name> = coupled_dynamics(<its lines type>, <lane force>)``
   (with its row set-up, a ``wp.func``, where its steps keep something of a row).
2. Write ``mdroll/forces/<name>.py``: its ``force_launch``, a function
   ``(prepared, params, d, offset, force, lifts, device) -> wp.Launch`` that reads the
   :class:`~mdroll.forces.prepared.PreparedLines` fields it needs and records the launch that
   writes ``force`` (``lifts``: the lift table and its origin when it needs one, else None),
   and, if it has a coupled step, ``(prepared) -> (kernel, lines)``.
3. Add one entry to :data:`REGISTRY` below: ``force_launch``, ``needs``, ``coupled`` (or None),
   ``exact``, ``max_window`` and ``complexity``.

The CLI's ``--algorithm`` choices, :data:`mdroll.ALGORITHMS`, the pipeline, the coupled
dynamics and the scaling study pick it up from there; the tests that compare every exact
algorithm with the direct sum (tests/test_force.py) run it too.
"""

from __future__ import annotations

from ..kernels.common import MAX_CLOSED_FORM_OFFSET
from ..errors import ParameterError
from .algorithm import BOUNDS, LIFTS, PREFIX, TREE, Algorithm, BenchVariant, Complexity
from .direct import direct_coupled, direct_launch
from .edge import edge_coupled, edge_launch
from .sweep import sweep_coupled, sweep_launch
from .tree import tree_coupled, tree_launch

#: Every algorithm by name.
REGISTRY: dict[str, Algorithm] = {
    a.name: a
    for a in (
        Algorithm(
            name="tree",
            description="the bounding-tree algorithm, equal to direct to rounding",
            exact=True,
            needs=frozenset({BOUNDS, PREFIX, TREE, LIFTS}),
            force_launch=tree_launch,
            coupled=tree_coupled,
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
            force_launch=direct_launch,
            coupled=direct_coupled,
            max_window=MAX_CLOSED_FORM_OFFSET,
            complexity=Complexity(refinement=2.0, text="O(n^2) a line under refinement"),
            # O(n^2): the largest sizes whose full study stays within minutes (docs/performance.md,
            # "Scaling study")
            bench_point_limit={"cpu": 2**20, "cuda": 2**26},
        ),
        Algorithm(
            name="edge",
            description="the edge-incremental approximation of eq 49",
            exact=False,
            needs=frozenset({PREFIX}),
            force_launch=edge_launch,
            coupled=edge_coupled,
            complexity=Complexity(refinement=1.0, text="O(n) a line"),
            bench_point_limit={"cpu": 2**23},
        ),
        Algorithm(
            name="sweep",
            description="exact in O(n) at fixed d: running totals over the springs in contact, equal to direct to "
                        "rounding (coupled: the core in closed form and the bands spring by spring)",
            exact=True,
            # the row bounds only: its CUDA stream sums each segment's anchor spring by spring;
            # the sequential form and the coupled step, which read prefix sums, build them on
            # first use (forces/sweep.py), so that the CUDA build is the bounds pass alone
            needs=frozenset({BOUNDS}),
            force_launch=sweep_launch,
            # d varies every step of the coupled dynamics, so no totals carry over there: its
            # step sums the bands directly (O(band) a step; see DEFAULT_ALGORITHMS)
            coupled=sweep_coupled,
            max_window=MAX_CLOSED_FORM_OFFSET,  # the core's closed form, sum of m^2
            prepares_ahead=True,  # its window of d's springs, built by helper warps
            complexity=Complexity(refinement=1.0, text="O(n) a line"),
            bench_point_limit={"cpu": 2**23},
        ),
    )
}

#: The algorithms' names (``algorithm=`` everywhere), in the registry's order: one entry of
#: :data:`REGISTRY` each.
ALGORITHMS = tuple(REGISTRY)
#: The algorithm each mode takes by default (:func:`mdroll.contact_force`, whose indentation is
#: fixed, takes the decoupled one; :func:`mdroll.run_ensemble`, :class:`mdroll.EnsembleSpec` and
#: the CLI take their mode's): the fastest exact one there. The sweep is exact and O(n) at fixed
#: d. In the coupled dynamics its step sums the bands directly, O(band) a step, which is faster
#: than the tree's descent at thesis scale and under refinement down to bands of several hundred
#: springs a side, below which the tree's descent wins (docs/performance.md, "Coupled dynamics").
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
