"""Ensembles on Dask distributed: many specs, many workers, one answer.

A list of :class:`~mdroll.ensemble.spec.EnsembleSpec` is cut into *work units* (a spec's slice of
consecutive realizations, :meth:`EnsembleSpec.split`). Each unit runs as one Dask task on a
worker, on that worker's device, and returns only binned accumulators: its
:class:`~mdroll.ensemble.result.EnsembleResult` (per-bin mean PSDs and their standard errors,
force sums, counts) — never a per-realization series. The client merges each spec's units in a
fixed order (by first realization) with the exact pairwise merge of means and variances
(:meth:`EnsembleResult.merge`, Chan et al.), so the result equals a one-process run to rounding
(<= 1e-12 relative) whatever the partition and the number of workers: every realization derives
from (seed, realization index) alone.

Faults. A worker that dies mid-unit loses only that unit's work: Dask reschedules it on another
worker, and the client keeps each unit's result under its id, so nothing is counted twice or
lost. With ``checkpoint=DIR`` every finished unit is written to ``DIR`` (atomically) as it
arrives; a later run with the same specs reads them back and computes only the missing units.

Warp across processes. Workers are separate processes started by *spawn* (Dask's nanny never
forks a process that holds a CUDA context), and each GPU worker is pinned to its GPU through
``CUDA_VISIBLE_DEVICES`` before it imports Warp (:func:`local_cluster`), so it sees its GPU as
``cuda:0``. Warp's kernel cache is shared: Warp builds each module in a private directory and
renames it into place, so concurrent compilation by several workers is safe.
"""

from __future__ import annotations

import contextlib
import json
import os
import uuid
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from tqdm.auto import tqdm

from .ensemble.result import EnsembleResult
from .ensemble.spec import EnsembleSpec
from .errors import ParameterError

# Dask's ``distributed`` is an optional dependency (the ``distributed`` extra): the functions that
# need it import it, so that this module imports without it.

#: Units per worker when the unit size is not given: small enough to balance the load and to
#: lose little work when a worker dies, large enough that a unit fills a batch.
UNITS_PER_WORKER = 4
#: A local cluster listens on the loopback interface only: it serves no one outside this machine.
LOOPBACK = "127.0.0.1"


@dataclass(frozen=True)
class WorkUnit:
    """One task: realizations ``spec.first .. spec.first + spec.realizations - 1`` of spec
    number ``spec_index`` of a run."""

    spec_index: int
    spec: EnsembleSpec

    @property
    def uid(self) -> str:
        """The unit's id, unique within a run: ``"<spec index>-<first>-<count>"``."""
        return f"{self.spec_index}-{self.spec.first}-{self.spec.realizations}"


def work_units(specs: Sequence[EnsembleSpec], unit_size: int) -> list[WorkUnit]:
    """Every spec cut into units of at most ``unit_size`` consecutive realizations, in order."""
    return [WorkUnit(i, part) for i, spec in enumerate(specs) for part in spec.split(unit_size)]


def default_unit_size(specs: Sequence[EnsembleSpec], workers: int) -> int:
    """About :data:`UNITS_PER_WORKER` units per worker over all specs (at least one realization)."""
    total = sum(spec.realizations for spec in specs)
    return max(1, -(-total // (UNITS_PER_WORKER * max(1, workers))))


def run_unit(spec: EnsembleSpec, device: str, options: dict) -> EnsembleResult:
    """The task a worker runs: one unit's ensemble, on the worker's own device."""
    return spec.run(device=device, progress=False, **options)


class DaskRunner:
    """Runs ensemble specs on a ``dask.distributed.Client``: the distributed back end of
    :func:`mdroll.run_specs` (pass it as ``runner=``).

    Parameters
    ----------
    client : dask.distributed.Client
        The cluster's client (:func:`local_cluster`, or ``Client("tcp://host:8786")``).
    unit_size : int, optional
        Realizations per work unit; default :func:`default_unit_size`.
    checkpoint : path, optional
        A directory that receives every finished unit (resumable).
    """

    def __init__(self, client, unit_size: int | None = None, checkpoint=None):
        if unit_size is not None and (isinstance(unit_size, bool) or not isinstance(unit_size, int) or unit_size < 1):
            raise ParameterError(f"unit_size = {unit_size!r} is not allowed: it must be a positive integer")
        self.client = client
        self.unit_size = unit_size
        self.checkpoint = None if checkpoint is None else Path(checkpoint)

    def workers(self) -> int:
        """The number of workers the scheduler knows now."""
        return len(self.client.scheduler_info()["workers"])

    def run_specs(self, specs: Iterable[EnsembleSpec], device: str = "auto", progress: bool = False,
                  **options) -> list[EnsembleResult]:
        """Every spec's result, merged from its units in a fixed order (see the module docstring)."""
        from distributed import as_completed

        specs = list(specs)
        units = work_units(specs, self.unit_size or default_unit_size(specs, self.workers()))
        done = self._load_checkpoint(specs, units)
        todo = [u for u in units if u.uid not in done]
        bar = _progress(len(units), progress)
        bar.update(len(units) - len(todo))
        run = uuid.uuid4().hex[:12]  # keys of this call only: a cancelled earlier run's keys never collide
        futures = {self.client.submit(run_unit, u.spec, device, options, key=f"mdroll-unit-{run}-{u.uid}"): u
                   for u in todo}
        try:
            for future in as_completed(futures):
                unit = futures[future]
                result = future.result()  # re-raises a unit's error (a ParameterError names its parameter)
                done[unit.uid] = result
                self._save_unit(unit, result)
                bar.update(1)
        finally:
            bar.close()
            for future in futures:  # after an error or an interrupt: stop what is still queued
                if not future.done():
                    future.cancel()
        return [EnsembleResult.merge([done[u.uid] for u in units if u.spec_index == i]) for i in range(len(specs))]

    # -- checkpoint: one file per finished unit, and a manifest naming the run's specs
    def _load_checkpoint(self, specs, units) -> dict:
        if self.checkpoint is None:
            return {}
        self.checkpoint.mkdir(parents=True, exist_ok=True)
        manifest = self.checkpoint / "manifest.json"
        planned = {"specs": [s.as_dict() for s in specs], "units": [u.uid for u in units]}
        if manifest.exists():
            saved = json.loads(manifest.read_text())
            if saved != planned:
                raise ParameterError(f"checkpoint {self.checkpoint} belongs to another distributed run "
                                     "(its specs or units differ): use another directory")
        else:
            _write_atomic(manifest, json.dumps(planned, indent=1).encode())
        done = {}
        for unit in units:
            path = self._unit_path(unit)
            if path.exists():
                done[unit.uid] = EnsembleResult.load(path)
        return done

    def _unit_path(self, unit: WorkUnit) -> Path:
        return self.checkpoint / f"unit-{unit.uid}.npz"

    def _save_unit(self, unit: WorkUnit, result: EnsembleResult) -> None:
        if self.checkpoint is None:
            return
        path = self._unit_path(unit)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp.npz")
        result.save(tmp)
        os.replace(tmp, path)


def _write_atomic(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def _progress(total: int, enabled: bool):
    """One bar over all units, with the ETA."""
    return tqdm(total=total, unit="unit", desc="work units", dynamic_ncols=True, disable=not enabled)


def local_cluster(workers: int, device: str = "auto"):
    """A ``dask.distributed.Client`` on a cluster of ``workers`` processes on this machine.

    ``device`` ``"cpu"``: processes of one thread each, sharing the cores. A CUDA device (or
    ``"auto"`` where GPUs are present): one process per GPU, ``workers`` at most the number of
    GPUs, each pinned to its GPU by ``CUDA_VISIBLE_DEVICES`` before Warp starts in it (so each
    worker's ``cuda:0`` is its own GPU). ``dask-cuda``'s ``LocalCUDACluster`` does the same; this
    spec needs only ``distributed``.
    """
    from distributed import Client, Nanny, Scheduler, SpecCluster

    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ParameterError(f"workers = {workers!r} is not allowed: it must be a positive integer")
    gpus = gpu_count() if device != "cpu" else 0
    if device.startswith("cuda") and gpus == 0:
        raise ParameterError(f"device = {device!r}: no GPU is visible to start GPU workers on")
    if gpus and workers > gpus:
        raise ParameterError(f"workers = {workers} is not allowed: this machine has {gpus} GPU(s), one worker each")
    visible = os.environ.get("CUDA_VISIBLE_DEVICES")
    ordinals = visible.split(",") if visible else [str(i) for i in range(gpus)]
    spec = {}
    for w in range(workers):
        env = {"OMP_NUM_THREADS": "1"}
        env["CUDA_VISIBLE_DEVICES"] = ordinals[w] if gpus else ""
        spec[f"mdroll-{w}"] = {"cls": Nanny, "options": {"nthreads": 1, "env": env, "memory_limit": 0,
                                                          "host": LOOPBACK, "dashboard": False}}
    scheduler = {"cls": Scheduler, "options": {"host": LOOPBACK, "dashboard": False,
                                                   "dashboard_address": f"{LOOPBACK}:0"}}
    cluster = SpecCluster(workers=spec, scheduler=scheduler, silence_logs=40)
    return Client(cluster)


@contextlib.contextmanager
def connect(workers: int | None = None, scheduler: str | None = None, device: str = "auto"):
    """A client for the duration of a ``with`` block: a :func:`local_cluster` of ``workers``
    processes (closed at the end), or the existing cluster at ``scheduler`` (an address such as
    ``tcp://host:8786``; left running)."""
    from distributed import Client

    if (workers is None) == (scheduler is None):
        raise ParameterError("give either workers (a local cluster) or scheduler (an existing cluster), not both")
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout="10s")
        except OSError as exc:
            raise ParameterError(f"scheduler = {scheduler!r}: cannot connect ({exc})") from None
        with client:
            yield client
        return
    client = local_cluster(workers, device)
    try:
        yield client
    finally:
        client.close()
        client.cluster.close()


def saved_specs(checkpoint) -> list[EnsembleSpec]:
    """The specs of the distributed run whose units are in the directory ``checkpoint``."""
    manifest = Path(checkpoint) / "manifest.json"
    if not manifest.is_file():
        raise ParameterError(f"{checkpoint}: no manifest.json of a distributed run there to continue from")
    return [EnsembleSpec.from_dict(d) for d in json.loads(manifest.read_text())["specs"]]


def gpu_count() -> int:
    """GPUs visible to this process, without creating a CUDA context in it (workers must start
    theirs after being pinned): from ``CUDA_VISIBLE_DEVICES`` or the NVIDIA driver's device
    nodes."""
    visible = os.environ.get("CUDA_VISIBLE_DEVICES")
    if visible is not None:
        return len([v for v in visible.split(",") if v.strip() not in ("", "-1")])
    return len([p for p in Path("/dev").glob("nvidia[0-9]*")])
