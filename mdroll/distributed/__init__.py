"""Ensembles on Dask distributed: many specs, many workers, one answer.

A list of :class:`~mdroll.ensemble.spec.EnsembleSpec` is cut into *work units* (a spec's slice of
consecutive realizations, :meth:`EnsembleSpec.split`), by default a worker's whole share
(:func:`default_unit_size`), which the worker runs as one process would: in batches sized from
its own device's free memory. Each unit runs as one Dask task on a worker, on that worker's
device, and becomes a part (:mod:`mdroll.distributed.parts`) that stays on that worker: its
per-bin spectra (means and standard errors of both PSDs) in one contiguous float64 array, which
Dask ships as one frame, beside the run's scalars (never a per-realization series). A spec of at
most two units sends its parts to the client as each unit ends; with more, each worker merges
its parts of each spec, the workers' parts are merged in pairs on the workers, and the client
receives the last two. The client merges them into the result: the exact pairwise merge of
means and variances (Chan et al.), so the result equals a one-process run to rounding (<= 1e-12
relative) whatever the partition and the number of workers: every realization derives from
(seed, realization index) alone.

Faults. A worker that dies loses only its units: Dask runs them again on another worker (the
finished ones too, their results being lost with it), each under its own key, so nothing is
counted twice or lost. A lost scheduler ends the run with :class:`SchedulerLost`. With
``checkpoint=DIR`` every worker writes each finished unit to ``DIR`` (atomically), next to a
manifest of the specs and unit sizes; a later run with the same specs reads them back and
computes only the missing units.

Warp across processes. Workers are separate processes started by *spawn* (Dask's nanny never
forks a process that holds a CUDA context), and each GPU worker is pinned to its GPU through
``CUDA_VISIBLE_DEVICES`` before it imports Warp (:mod:`mdroll.distributed.cluster`), so it sees
its GPU as ``cuda:0``. Warp's kernel cache is shared: Warp builds each module in a private
directory and renames it into place, so concurrent compilation by several workers is safe.
"""

from __future__ import annotations

import concurrent.futures
import json
import os
import uuid
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from tqdm.auto import tqdm

from ..ensemble.result import EnsembleResult
from ..ensemble.spec import EnsembleSpec
from ..errors import ParameterError, SchedulerLost
from .cluster import connect, local_cluster
from .parts import Part, PartSum, merge_parts, part_of, result_of

# the clients and the parts, from here as from their modules
__all__ = ["DaskRunner", "WorkUnit", "connect", "default_unit_size", "local_cluster", "merge_parts", "part_of",
           "result_of", "run_unit", "saved_specs", "work_units"]

# Dask's ``distributed`` is an optional dependency (the ``distributed`` extra): the functions that
# need it import it, so that this package imports without it.

#: The file of a checkpoint directory that names its run's specs and unit sizes.
MANIFEST = "manifest.json"


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


def work_units(specs: Sequence[EnsembleSpec], sizes: int | Sequence[int]) -> list[WorkUnit]:
    """Every spec cut into units of at most ``sizes`` (one for all, or one per spec) consecutive
    realizations, in order."""
    sizes = [sizes] * len(specs) if isinstance(sizes, int) else list(sizes)
    return [WorkUnit(i, part) for i, (spec, size) in enumerate(zip(specs, sizes)) for part in spec.split(size)]


def default_unit_size(total: int, workers: int) -> int:
    """Realizations per unit for ``total`` realizations on ``workers`` workers: one unit a worker,
    its whole share, which its device runs in as few batches as its memory allows. A second unit
    a worker would let a faster worker take it, but costs a unit's start and a merge over every
    bin more than it balances between equal GPUs (docs/distributed.md, "Measured"); a cluster
    of unequal devices passes ``unit_size``."""
    return max(1, -(-total // max(1, workers)))


def run_unit(spec: EnsembleSpec, device: str, options: dict, checkpoint: str | None = None,
             uid: str = "") -> Part:
    """The task a worker runs: one unit's ensemble on the worker's own device, batched from its
    free memory as in one process (unless ``options`` give ``batch`` or ``memory_limit``), as a
    :data:`~mdroll.distributed.parts.Part` that stays on the worker
    (:func:`~mdroll.distributed.parts.merge_parts` reduces it there); with a
    checkpoint the worker also writes the result to ``checkpoint/unit-<uid>.npz`` (atomically)."""
    if checkpoint is not None and not (Path(checkpoint) / MANIFEST).is_file():
        raise ParameterError(f"checkpoint {checkpoint} is not visible to every worker: on a cluster of several "
                             "machines it must be on a file system that all of them share")
    result = spec.run(device=device, progress=False, **options)
    if checkpoint is not None:
        result.save(Path(checkpoint) / f"unit-{uid}.npz")
    return part_of(result, spec.first)


class DaskRunner:
    """Runs ensemble specs on a ``dask.distributed.Client``: the distributed back end of
    :func:`mdroll.run_specs` (pass it as ``runner=``).

    Parameters
    ----------
    client : dask.distributed.Client
        The cluster's client (:func:`~mdroll.distributed.cluster.local_cluster`, or ``Client("tcp://host:8786")``).
    unit_size : int, optional
        Realizations per work unit; default :func:`default_unit_size`, a worker's share.
    checkpoint : path, optional
        A directory that receives every finished unit (resumable); the workers write it, so on
        several machines it must be on a shared file system.
    """

    def __init__(self, client, unit_size: int | None = None, checkpoint=None):
        if unit_size is not None and (isinstance(unit_size, bool) or not isinstance(unit_size, int) or unit_size < 1):
            raise ParameterError(f"unit_size = {unit_size!r} is not allowed: it must be a positive integer")
        self.client = client
        self.unit_size = unit_size
        self.checkpoint = None if checkpoint is None else Path(checkpoint).absolute()

    def workers(self) -> int:
        """The number of workers the scheduler knows now."""
        return len(self.client.scheduler_info()["workers"])

    def _workers_now(self) -> int:
        """The number of workers, once there is one."""
        count = self.workers()
        if count == 0:
            self.client.wait_for_workers(1)
            count = self.workers()
        return count

    def run_specs(self, specs: Iterable[EnsembleSpec], device: str = "auto", progress: bool = False,
                  **options) -> list[EnsembleResult]:
        """Every spec's result (see the module docstring): units of a worker's share run on the
        workers, reduced there, and shipped to the client once per worker and spec."""
        from distributed import as_completed

        specs = list(specs)
        checkpoint = None if self.checkpoint is None else str(self.checkpoint)
        run = uuid.uuid4().hex[:12]  # keys of this call only: a cancelled earlier run's keys never collide
        futures = {}
        try:
            saved = None if self.checkpoint is None else self._manifest(specs)
            total = sum(s.realizations for s in specs)
            sizes = saved or [self.unit_size or default_unit_size(total, self._workers_now())] * len(specs)
            if self.checkpoint is not None and saved is None:
                self._manifest(specs, sizes)
            units = work_units(specs, sizes)
            done = self._load_checkpoint(units)
            todo = [u for u in units if u.uid not in done]
            bar = _progress(len(units), progress)
            bar.update(len(units) - len(todo))
            for u in todo:
                future = self.client.submit(run_unit, u.spec, device, options, checkpoint, u.uid,
                                            key=f"mdroll-unit-{run}-{u.uid}")
                futures[future] = u
            # at most two units a spec (one a worker, on one or two workers): their parts are the
            # reduction's last level, which the client takes and merges as each unit ends
            count = Counter(u.spec_index for u in todo)
            early = max(count.values(), default=0) <= 2
            sums = [PartSum(eager=early and count[i] > 1) for i in range(len(specs))]
            try:
                for item in as_completed(futures, with_results=early):
                    future = item[0] if early else item
                    if future.status != "finished":
                        future.result()  # re-raises a unit's error (a ParameterError names its parameter)
                    if early:
                        sums[futures[future].spec_index].add(item[1])
                    bar.update(1)
            finally:
                bar.close()
            for i, parts in ({} if early else self._reduce_on_workers(futures, run)).items():
                for part in parts:
                    sums[i].add(part)
        except (OSError, TimeoutError, concurrent.futures.CancelledError) as exc:
            if self.client.status == "running":  # the scheduler is there: not a lost connection
                raise
            kept = f"; the finished units are kept in {checkpoint} (resume from them)" if checkpoint else ""
            raise SchedulerLost(f"lost the Dask scheduler at {self.client.scheduler.address} "
                                f"({type(exc).__name__}){kept}") from None
        finally:
            for future in futures:  # after an error or an interrupt: stop what is still queued
                if not future.done():
                    future.cancel()
        for u in units:
            if u.uid in done:
                sums[u.spec_index].add(done[u.uid])
        return [result_of(total.part()) for total in sums]

    def _reduce_on_workers(self, futures: dict, run: str) -> dict:
        """Each worker's parts of each spec merged on that worker, then the workers' parts merged in
        pairs on the workers (a tree: log2 of the workers' number of steps, each moving one part
        between two workers) down to two, which the client receives at once: each spec's list of
        at most two parts. A lost worker's units are computed again by Dask, from their tasks."""
        holders = self.client.who_has(list(futures))
        groups: dict = {}
        for future, unit in futures.items():
            where = (holders.get(future.key) or [None])[0]
            groups.setdefault((unit.spec_index, where), []).append(future)
        level: dict = {}
        for n, ((spec_index, where), group) in enumerate(groups.items()):
            level.setdefault(spec_index, []).append(group[0] if len(group) == 1 else self.client.submit(
                merge_parts, *group, workers=None if where is None else [where], allow_other_workers=True,
                key=f"mdroll-merge-{run}-{n}"))
        step = 0
        while any(len(parts) > 2 for parts in level.values()):  # the last two go to the client at once
            step += 1
            level = {i: [self.client.submit(merge_parts, *parts[k:k + 2], key=f"mdroll-merge-{run}-{step}-{i}-{k}")
                         if k + 1 < len(parts) else parts[k] for k in range(0, len(parts), 2)]
                     for i, parts in level.items()}
        return self.client.gather(level)

    # -- checkpoint: one file per finished unit (written by the workers), and a manifest of the
    # run's specs and unit sizes (a resumed run keeps them, whatever its number of workers)
    def _manifest(self, specs, sizes=None) -> list[int] | None:
        """Write the manifest (the sizes once they are known); return the sizes it holds."""
        self.checkpoint.mkdir(parents=True, exist_ok=True)
        manifest = self.checkpoint / MANIFEST
        planned = [s.as_dict() for s in specs]
        saved = json.loads(manifest.read_text()) if manifest.exists() else {"specs": planned, "sizes": None}
        if saved.get("specs") != planned:
            raise ParameterError(f"checkpoint {self.checkpoint} belongs to another distributed run "
                                 "(its specs differ): use another directory")
        if saved.get("sizes") is None:
            saved["sizes"] = sizes
            _write_atomic(manifest, json.dumps(saved, indent=1).encode())
        return saved["sizes"]

    def _load_checkpoint(self, units) -> dict:
        """The finished units' parts, by id; a unit's file must hold its realizations."""
        parts = {}
        for u in units if self.checkpoint is not None else ():
            path = self.checkpoint / f"unit-{u.uid}.npz"
            if path.exists():
                result = EnsembleResult.load(path)
                if result.realizations != list(u.spec.indices):
                    raise ParameterError(f"{path} does not hold the realizations {u.spec.first} to "
                                         f"{u.spec.first + u.spec.realizations - 1} its name gives: it was edited")
                parts[u.uid] = part_of(result, u.spec.first)
        return parts


def _write_atomic(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def _progress(total: int, enabled: bool):
    """One bar over all units, with the ETA."""
    return tqdm(total=total, unit="unit", desc="work units", dynamic_ncols=True, disable=not enabled)


def saved_specs(checkpoint) -> list[EnsembleSpec]:
    """The specs of the distributed run whose units are in the directory ``checkpoint``."""
    manifest = Path(checkpoint) / MANIFEST
    if not manifest.is_file():
        raise ParameterError(f"{checkpoint}: no {MANIFEST} of a distributed run there to continue from")
    return [EnsembleSpec.from_dict(d) for d in json.loads(manifest.read_text())["specs"]]
