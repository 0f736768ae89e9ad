"""The thesis's parameter studies (chapters 4-6): each reproduces a figure, measures what it
claimed with standard errors from the ensembles, and gives a verdict per claim.

``run_study(name, size)`` runs one study of :data:`STUDIES` through the shared sweep runner
(:func:`mdroll.run_specs`) and returns a :class:`StudyRun`: its JSON record (every measured
number with its standard error, every ensemble spec, seed, device, versions and commit) and its
figures; :mod:`mdroll.studies.report` writes them and prints the table. Sizes: the rungs of
:data:`mdroll.experiments.SIZES` (``test`` for the test suite, ``quick`` on a CPU, ``full`` the
thesis's ensembles: 300 realizations for chapters 4-5, 100 per point for chapter 6, on a GPU).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

from ..devices import resolve_device
from ..experiments import Ladder, Registry, provenance
from ..files import jsonable
from . import coupling, high_band, low_band, regions, taper
from .mdr3d import mdr_vs_3d
from .core import AGREES, DISAGREES, REPORTED, UNRESOLVED, Claim, Runner

#: Thesis-scale line: 2^20 springs of 5 um (the thesis's 5 m, rounded up to a fast FFT length).
THESIS = {"L": 5.24288, "dx": 5e-6}
CPU_QUICK = {"L": 1.0, "dx": 20e-6}
CPU_TEST = {"L": 0.5, "dx": 20e-6}
#: The MDR-against-3-D sweep's defaults: every surface and indenter at H 0.7 (rungs widen it).
MDR3D_SWEEP = {"surfaces": ("a", "b", "c"), "indenters": ("sphere", "ellipse"), "hursts": (0.7,)}


@dataclass(frozen=True)
class Study:
    """A study: its function ``run(runner, **rung)``, the thesis's figures and equations it
    reproduces, and its keyword arguments per rung (a :class:`~mdroll.experiments.Ladder`)."""

    name: str
    function: Callable
    figures: str
    equations: str
    title: str
    ladder: Ladder


STUDIES = Registry("study", ((s.name, s) for s in [
    Study("regions", regions.regions, "Fig 2", "sec 4.1-4.2, eq 21, 23",
          "the four regions of the acceleration spectrum, located numerically",
          Ladder(test={**CPU_TEST, "realizations": 32}, quick={"L": 2.0, "dx": 20e-6, "realizations": 192},
                 full={**THESIS, "realizations": 300})),
    Study("transition", regions.transition, "Fig 3", "eq 21",
          "the transition at q_min v0 for three cutoffs, with and without renormalizing h0",
          Ladder(test={**CPU_TEST, "realizations": 16}, quick={"L": 1.0, "dx": 10e-6, "realizations": 64},
                 full={**THESIS, "realizations": 300})),
    Study("slope", high_band.slope, "Fig 4", "eq 23",
          "the power-law exponent alpha(H) against 2H + 3",
          Ladder(test={**CPU_TEST, "realizations": 24, "hursts": (0.3, 0.6, 0.9)},
                 quick={**CPU_QUICK, "realizations": 96}, full={**THESIS, "realizations": 300})),
    Study("modulation", high_band.modulation, "Fig 5-6", "eq 26-27",
          "the modulation period pi v0 / a, and the transform of eq 27",
          Ladder(test={**CPU_TEST, "realizations": 16}, quick={**CPU_QUICK, "realizations": 96},
                 full={**THESIS, "realizations": 300})),
    Study("rms", high_band.rms, "Fig 7", "eq 28",
          "the exponent of h0 in the high and the low band",
          Ladder(test={**CPU_TEST, "realizations": 24}, quick={**CPU_QUICK, "realizations": 128},
                 full={**THESIS, "realizations": 300})),
    Study("taper", taper.taper, "Fig 8", "sec 4.3.5",
          "the cause of the taper-off: leakage, non-linearity or discretization",
          Ladder(test={"lengths": (0.25, 0.5, 1.0), "dx": 20e-6, "realizations": 12},
                 quick={"lengths": (0.25, 0.5, 1.0, 2.0, 4.0), "dx": 20e-6, "realizations": 64},
                 full={"lengths": (1.31072, 2.62144, 5.24288, 10.48576), "dx": 5e-6, "realizations": 300})),
    Study("proportionality", high_band.proportionality, "Fig 9", "eq 29-31, 40",
          "the acceleration PSD against C_1D(q) q^-2: fitted and predicted constants",
          Ladder(test={**CPU_TEST, "realizations": 32}, quick={**CPU_QUICK, "realizations": 192},
                 full={**THESIS, "realizations": 300})),
    Study("coupling", coupling.coupling, "Fig 11", "sec 5.1, eq 13",
          "coupled against decoupled dynamics, band by band",
          Ladder(test={"L": 0.5, "dx": 20e-6, "realizations": 8}, quick={"L": 2.0, "dx": 20e-6, "realizations": 48},
                 full={**THESIS, "realizations": 300})),
    Study("low-band", low_band.low_band, "Fig 13", "eq 48",
          "the exact low band against eq 48 and the closed form",
          Ladder(test={**CPU_TEST, "realizations": 16}, quick={**CPU_QUICK, "realizations": 128},
                 full={**THESIS, "realizations": 300})),
    Study("plateau", low_band.plateau, "Fig 14-20", "eq 51-58",
          "the low-frequency plateau B_F0 and the refit of the empirical law eq 56",
          Ladder(test={**CPU_TEST, "realizations": 16, "hursts": (0.3, 0.55, 0.8), "q_min_factors": (0.5, 1.0, 2.0),
                       "heights": (0.5e-6, 1e-6), "length_factors": (2.0,)},
                 quick={**CPU_QUICK, "realizations": 64}, full={**THESIS, "realizations": 100})),
    Study("mdr-vs-3d", mdr_vs_3d, "sec 7.1", "eq 39-40, 48",
          "the MDR's force spectrum against the 3-D boundary-element reference, and the contact filters",
          Ladder(test={**MDR3D_SWEEP, "surfaces": ("a", "b"), "indenters": ("sphere",), "ratios": (0.01,),
                       "qmin_as": (0.5,), "realizations": 2, "cells": 21, "positions": 48},
                 quick={**MDR3D_SWEEP, "ratios": (0.01, 0.1), "qmin_as": (0.5, 5.0), "realizations": 3, "cells": 23,
                        "positions": 128},
                 full={**MDR3D_SWEEP, "hursts": (0.3, 0.5, 0.7, 0.9), "ratios": (0.003, 0.01, 0.03, 0.1),
                       "qmin_as": (0.5, 1.58, 5.0), "realizations": 8, "cells": 47, "positions": 768})),
    Study("rms-force", low_band.rms_force, "eq 59-61", "eq 59-61",
          "the RMS force in the plateau band of the thesis's example",
          Ladder(test={**CPU_TEST, "realizations": 32}, quick={**CPU_QUICK, "realizations": 192},
                 full={**THESIS, "realizations": 100})),
]))


@dataclass
class StudyRun:
    """A study's JSON record (see :func:`run_study`) and its figures
    (:class:`~mdroll.experiments.Figure`)."""

    record: dict
    figures: list


def check_name(name: str) -> Study:
    """The study ``name`` of :data:`STUDIES`, or a one-line ParameterError."""
    return STUDIES.named(name)


def run_study(name: str, size: str = "quick", device: str = "auto", seed: int = 0, progress: bool = False,
              cluster=None, **overrides) -> StudyRun:
    """Run the study ``name`` at ``size`` (``test``, ``quick`` or ``full``; ``overrides`` replace
    any of that size's keyword arguments) on ``device`` with master seed ``seed``; ``cluster``: a
    runner for :func:`mdroll.run_specs` (e.g. :class:`mdroll.distributed.DaskRunner`).

    The record holds: the study, its figures and equations, the size and its arguments, every
    claim (thesis claim, expected value and whose it is, measured value, standard error, unit,
    allowance, verdict, notes), every other measured number, each ensemble's spec
    (:meth:`mdroll.EnsembleSpec.as_dict`: parameters, seed, realizations, algorithm, mode,
    boundary, window), steps and time, and the provenance of :func:`mdroll.experiments.provenance`
    (environment: device, versions, date; git commit).
    """
    study = check_name(name)
    device = resolve_device(device) if cluster is None else device
    arguments = {**study.ladder.rung(size), **overrides}
    runner = Runner(device, seed, progress, cluster)
    start = time.perf_counter()
    outcome = study.function(runner, **arguments)
    elapsed = time.perf_counter() - start
    claims = outcome.claims
    record = {
        "study": study.name, "title": study.title, "thesis_figures": study.figures, "equations": study.equations,
        "arguments": arguments, "device": device,
        "verdicts": {v: sum(c.verdict == v for c in claims) for v in (AGREES, DISAGREES, UNRESOLVED, REPORTED)},
        "claims": [c.as_dict() for c in claims], "measurements": outcome.measurements,
        "resolution": outcome.resolution, "summary": outcome.summary, "ensembles": runner.record, "elapsed_s": elapsed,
        # the ensembles' devices are in each ensemble's record; this is the process that ran the study
        **provenance(device if cluster is None else resolve_device("auto"), size, seed, arguments),
        "cluster": None if cluster is None else type(cluster).__name__,
        "figures": [{"file": f"{f.name}.png", "caption": f.caption} for f in outcome.figures],
    }
    return StudyRun(jsonable(record), outcome.figures)


__all__ = ["AGREES", "DISAGREES", "REPORTED", "STUDIES", "UNRESOLVED", "Claim", "Study", "StudyRun",
           "check_name", "run_study"]
