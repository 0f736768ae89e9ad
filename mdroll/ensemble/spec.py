"""Ensemble specs and the sweep runner: what to compute, apart from where and how it is run.

An :class:`EnsembleSpec` names one ensemble completely (parameters, seed, realization range,
algorithm, dynamics mode, boundary, window), so that its result depends on the spec alone,
never on the device, the batch size or the split into work units: every realization derives
from (seed, realization index). :func:`run_specs` is the one sweep runner that the studies, the
validation checks and the inverse problem's bootstrap go through; a distributed runner plugs in
behind the same call.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Iterable
from dataclasses import dataclass

from ..arguments import check_params
from ..errors import ParameterError
from ..params import Params
from ..roughness.kinds import check_spectrum
from .lines import check_seed
from .realizations import read_params
from ..forces.registry import default_algorithm


@dataclass(frozen=True)
class EnsembleSpec:
    """One ensemble: ``realizations`` consecutive realizations from index ``first``.

    Attributes
    ----------
    params : Params
        Physical and numerical parameters (SI units).
    seed : int
        Master seed in [0, 2^64).
    first, realizations : int
        The realization indices ``first .. first + realizations - 1``.
    algorithm, mode, boundary : str
        As for :func:`mdroll.run_ensemble`; the algorithm by default the registry's for the mode.
    window : bool
        Hann window on the force and acceleration series before their PSDs (default; False:
        the thesis's unwindowed record).
    roughness : mdroll.roughness.kinds.RoughnessSpectrum or None
        A spectrum instead of the one the roughness fields of ``params`` name (None: those).
        Serialized by its description; a callable spectrum cannot be read back.
    integrator : str
        The time step of the coupled dynamics (:func:`mdroll.run_ensemble`; "forward-euler", the
        thesis's scheme, only for the coupling study).
    """

    params: Params
    seed: int = 0
    first: int = 0
    realizations: int = 1
    algorithm: str | None = None
    mode: str = "decoupled"
    boundary: str = "open"
    window: bool = True
    roughness: object = None
    integrator: str = "semi-implicit"

    def __post_init__(self) -> None:
        check_params(self.params)
        check_spectrum(self.roughness)
        check_seed(self.seed)
        if self.algorithm is None:  # the registry's default for the mode
            object.__setattr__(self, "algorithm", default_algorithm(self.mode))
        for name in ("first", "realizations"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int):
                raise ParameterError(f"{name} must be an integer, got {value!r}")
        if self.first < 0:
            raise ParameterError(f"first = {self.first!r} is not allowed: it must be >= 0")
        if self.realizations < 1:
            raise ParameterError(f"realizations = {self.realizations!r} is not allowed: it must be at least 1")

    @property
    def indices(self) -> range:
        """The realization indices of this spec."""
        return range(self.first, self.first + self.realizations)

    def split(self, size: int) -> list["EnsembleSpec"]:
        """Consecutive specs of at most ``size`` realizations that together are this one."""
        if isinstance(size, bool) or not isinstance(size, int) or size < 1:
            raise ParameterError(f"size = {size!r} is not allowed: it must be a positive integer")
        return [dataclasses.replace(self, first=start, realizations=min(size, self.first + self.realizations - start))
                for start in range(self.first, self.first + self.realizations, size)]

    def as_dict(self) -> dict:
        """A JSON-ready dict; :meth:`from_dict` inverts it."""
        out = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        out["params"] = self.params.as_dict()
        out["roughness"] = None if self.roughness is None else self.roughness.describe()
        return out

    @classmethod
    def from_dict(cls, data: dict) -> "EnsembleSpec":
        """The spec of :meth:`as_dict`'s dict; a count inside its parameters (``n_real``, as
        specs once held it) is dropped: the spec's ``realizations`` name its realizations."""
        from ..roughness.line_grid import from_description

        data = dict(data)
        roughness = data.pop("roughness", None)
        return cls(params=read_params(data.pop("params"))[0],
                   roughness=None if roughness is None else from_description(roughness), **data)

    def key(self) -> str:
        """A hex digest of the spec and the mdroll version: equal keys, equal results (to rounding)."""
        from .._version import __version__

        text = json.dumps({"spec": self.as_dict(), "mdroll": __version__}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()

    def run(self, device: str = "auto", progress: bool = False, **options):
        """Run this ensemble with :func:`mdroll.run_ensemble` (``options``: batch, memory_limit,
        checkpoint, ...); returns its :class:`~mdroll.ensemble.pipeline.EnsembleResult`."""
        from .pipeline import run_ensemble

        return run_ensemble(self.params, seed=self.seed, realizations=self.indices, algorithm=self.algorithm,
                            mode=self.mode, boundary=self.boundary, window=self.window, device=device,
                            progress=progress, roughness=self.roughness, integrator=self.integrator, **options)


def run_specs(specs: Iterable[EnsembleSpec], device: str = "auto", progress: bool = False, runner=None,
              **options) -> list:
    """Every spec's result, in the specs' order: the sweep runner of the studies, the checks and
    the bootstraps (``options`` go to :meth:`EnsembleSpec.run`).

    ``runner=None`` runs the specs one after the other in this process, on ``device``. A runner
    object with the same ``run_specs(specs, device, progress, **options)`` method runs them
    elsewhere: :class:`mdroll.distributed.DaskRunner` spreads them over a Dask cluster (there
    ``device`` is resolved on each worker). The results are the same to rounding either way.
    Returns one :class:`mdroll.EnsembleResult` per spec (its units: :func:`mdroll.run_ensemble`).
    """
    if isinstance(specs, (EnsembleSpec, Params, str, bytes)) or not isinstance(specs, Iterable):
        raise ParameterError(f"specs must be a list of mdroll.EnsembleSpec, got {type(specs).__name__}")
    specs = list(specs)
    for number, spec in enumerate(specs):
        if not isinstance(spec, EnsembleSpec):
            raise ParameterError(f"specs[{number}] is a {type(spec).__name__}, not an mdroll.EnsembleSpec (wrap "
                                 "parameters as EnsembleSpec(params, realizations=N))")
    if runner is not None:
        return runner.run_specs(specs, device=device, progress=progress, **options)
    return [spec.run(device=device, progress=progress, **options) for spec in specs]
