"""What a force algorithm is: the :class:`Algorithm` record of the registry
(:mod:`mdroll.forces.registry`) and the prepared data it may declare that it needs."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

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
    go to :func:`~mdroll.forces.prepare.prepare_lines`; ``refinement`` as in :class:`Complexity`."""

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
        What :func:`~mdroll.forces.prepare.prepare_lines` prepares for it (:data:`BOUNDS`,
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
    prepares_ahead : bool
        Its coupled kernel's steps can be prepared ahead by helper warps
        (:func:`~mdroll.kernels.dynamics.with_helpers` gives its helped variant), which plans a
        coupled run's batches on CUDA (:func:`mdroll.ensemble.coupled.coupled_plan`).
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
    prepares_ahead: bool = False
    bench_variants: tuple = ()
    bench_point_limit: dict = field(default_factory=dict)
