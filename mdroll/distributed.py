"""Ensembles on Dask distributed: many specs, many workers, one answer.

A list of :class:`~mdroll.ensemble.spec.EnsembleSpec` is cut into *work units* (a spec's slice of
consecutive realizations, :meth:`EnsembleSpec.split`), by default a worker's whole share
(:func:`default_unit_size`), which the worker runs as one process would: in batches sized from
its own device's free memory. Each unit runs as one Dask task on a worker, on that worker's
device, and becomes a :data:`Part` that stays on that worker: its per-bin spectra (means and
standard errors of both PSDs) in one contiguous float64 array, which Dask ships as one frame,
beside the run's scalars (never a per-realization series). When all are done, each worker
merges its parts of each spec, the workers' parts are merged in pairs on the workers, and the
client receives at most two parts per spec (as their units end, where a spec has no more
units) and makes the result: the exact pairwise merge of
means and variances (:func:`merge_parts`, Chan et al.), so the result equals a one-process run to
rounding (<= 1e-12 relative) whatever the partition and the number of workers: every
realization derives from (seed, realization index) alone.

Faults. A worker that dies loses only its units: Dask runs them again on another worker (the
finished ones too, their results being lost with it), each under its own key, so nothing is
counted twice or lost. A lost scheduler ends the run with :class:`SchedulerLost`. With
``checkpoint=DIR`` every worker writes each finished unit to ``DIR`` (atomically), next to a
manifest of the specs and unit sizes; a later run with the same specs reads them back and
computes only the missing units.

Warp across processes. Workers are separate processes started by *spawn* (Dask's nanny never
forks a process that holds a CUDA context), and each GPU worker is pinned to its GPU through
``CUDA_VISIBLE_DEVICES`` before it imports Warp (:func:`local_cluster`), so it sees its GPU as
``cuda:0``. Warp's kernel cache is shared: Warp builds each module in a private directory and
renames it into place, so concurrent compilation by several workers is safe.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import dataclasses
import itertools
import json
import logging
import os
import uuid
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from .devices import cpu_cores
from .ensemble.psd import RunningMoments, wavenumbers
from .ensemble.result import EnsembleResult
from .ensemble.spec import EnsembleSpec
from .errors import ParameterError, SchedulerLost

# Dask's ``distributed`` is an optional dependency (the ``distributed`` extra): the functions that
# need it import it, so that this module imports without it.

#: A local cluster listens on the loopback interface only: it serves no one outside this machine.
LOOPBACK = "127.0.0.1"
#: The file of a checkpoint directory that names its run's specs and unit sizes.
MANIFEST = "manifest.json"
#: The rows of a part's spectra array, per bin: each PSD's mean over the part's realizations and
#: its standard error.
SPECTRA = ("force_psd", "force_psd_stderr", "accel_psd", "accel_psd_stderr")
#: A part of a spec's result as the workers hold and ship it: ``(spectra, bare, spans)``, the
#: (4, bins) float64 array of :data:`SPECTRA` first (so that Dask sends it as one frame, not
#: inside a pickle), the result's other fields (an :class:`EnsembleResult` whose arrays are
#: empty and whose realizations are in ``spans``) and its realizations as sorted, disjoint
#: ``(first, count)`` ranges.
Part = tuple
_EMPTY = np.empty(0)


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
    :data:`Part` that stays on the worker (:func:`merge_parts` reduces it there); with a
    checkpoint the worker also writes the result to ``checkpoint/unit-<uid>.npz`` (atomically)."""
    if checkpoint is not None and not (Path(checkpoint) / MANIFEST).is_file():
        raise ParameterError(f"checkpoint {checkpoint} is not visible to every worker: on a cluster of several "
                             "machines it must be on a file system that all of them share")
    result = spec.run(device=device, progress=False, **options)
    if checkpoint is not None:
        result.save(Path(checkpoint) / f"unit-{uid}.npz")
    return part_of(result, spec.first)


def part_of(result: EnsembleResult, first: int) -> Part:
    """The :data:`Part` of a result of the consecutive realizations from ``first``."""
    bare = dataclasses.replace(result, q=_EMPTY, omega=_EMPTY, **dict.fromkeys(SPECTRA, _EMPTY), realizations=[])
    return np.stack([getattr(result, name) for name in SPECTRA]), bare, ((first, result.n_real),)


def merge_parts(*parts: Part) -> Part:
    """One part of several of one spec (one is itself): the reduction's task on the workers, and
    its last step on the client. The spectra merge exactly (Chan et al., as the batches of one
    run), all fields at once; the other fields and the refusals of parts that do not belong
    together are :meth:`EnsembleResult.merge_own`'s, on the arrayless results."""
    if len(parts) == 1:
        return parts[0]
    bare = EnsembleResult.merge_own([bare for _, bare, _ in parts])
    spans = tuple(sorted(span for _, _, spans in parts for span in spans))
    for (first, count), (after, _) in zip(spans, spans[1:]):
        if first + count > after:
            raise ParameterError(f"cannot merge parts that share realization {after} (it would count twice)")
    moments = RunningMoments(parts[0][0][0::2].shape)  # the force's and acceleration's bins at once
    for spectra, part, _ in parts:
        n = part.n_real
        moments.merge(n, spectra[0::2], spectra[1::2] ** 2 * n * (n - 1))
    spectra = np.empty_like(parts[0][0])
    spectra[0::2], spectra[1::2] = moments.mean_and_stderr()
    return spectra, bare, spans


def result_of(part: Part) -> EnsembleResult:
    """The :class:`EnsembleResult` of a part: its grid (as the run computes it), spectra and
    realizations in order."""
    spectra, bare, spans = part
    q = wavenumbers(bare.steps, bare.params.dx)
    return dataclasses.replace(bare, q=q, omega=q * bare.params.v0, **dict(zip(SPECTRA, spectra)),
                               realizations=list(itertools.chain.from_iterable(range(f, f + n) for f, n in spans)))


class DaskRunner:
    """Runs ensemble specs on a ``dask.distributed.Client``: the distributed back end of
    :func:`mdroll.run_specs` (pass it as ``runner=``).

    Parameters
    ----------
    client : dask.distributed.Client
        The cluster's client (:func:`local_cluster`, or ``Client("tcp://host:8786")``).
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
            # reduction's last level, which the client takes as each unit ends
            early = max(Counter(u.spec_index for u in todo).values(), default=0) <= 2
            fetched: dict = {}
            try:
                for item in as_completed(futures, with_results=early):
                    future = item[0] if early else item
                    if future.status != "finished":
                        future.result()  # re-raises a unit's error (a ParameterError names its parameter)
                    if early:
                        fetched.setdefault(futures[future].spec_index, []).append(item[1])
                    bar.update(1)
            finally:
                bar.close()
            parts = fetched if early else self._reduce_on_workers(futures, run)
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
        return [result_of(merge_parts(*parts.get(i, []), *(done[u.uid] for u in units
                                                           if u.spec_index == i and u.uid in done)))
                for i in range(len(specs))]

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


def local_cluster(workers: int, device: str = "auto", verbose: bool = False):
    """A ``dask.distributed.Client`` on a cluster of ``workers`` processes on this machine.

    ``device`` ``"cpu"``: processes of one thread each, at most one per core. A CUDA device (or
    ``"auto"`` where GPUs are present): one process per GPU, ``workers`` at most the number of
    GPUs, each pinned to its GPU by ``CUDA_VISIBLE_DEVICES`` before Warp starts in it (so each
    worker's ``cuda:0`` is its own GPU). ``dask-cuda``'s ``LocalCUDACluster`` does the same; this
    spec needs only ``distributed``. The client takes the units' parts from the workers directly,
    not through the scheduler (one hop, not two: the workers are on this machine). Dask's logs
    below warnings are shown only when ``verbose``.
    """
    from distributed import Client, Nanny, Scheduler, SpecCluster

    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ParameterError(f"workers = {workers!r} is not allowed: it must be a positive integer")
    gpus = gpu_count() if device != "cpu" else 0
    if device.startswith("cuda") and gpus == 0:
        raise ParameterError(f"device = {device!r}: no GPU is visible to start GPU workers on")
    if gpus and workers > gpus:
        raise ParameterError(f"workers = {workers} is not allowed: at most {gpus}, one worker per GPU of this machine")
    if not gpus and workers > cpu_cores():
        raise ParameterError(f"workers = {workers} is not allowed: at most {cpu_cores()}, one CPU worker per core "
                             "this process may use")
    level = logging.INFO if verbose else logging.WARNING
    visible = os.environ.get("CUDA_VISIBLE_DEVICES")
    ordinals = visible.split(",") if visible else [str(i) for i in range(gpus)]
    spec = {}
    for w in range(workers):
        env = {"OMP_NUM_THREADS": "1", "DASK_LOGGING__DISTRIBUTED": logging.getLevelName(level).lower()}
        env["CUDA_VISIBLE_DEVICES"] = ordinals[w] if gpus else ""
        spec[f"mdroll-{w}"] = {"cls": Nanny, "options": {"nthreads": 1, "env": env, "memory_limit": 0,
                                                          "host": LOOPBACK, "dashboard": False,
                                                          "silence_logs": level}}
    scheduler = {"cls": Scheduler, "options": {"host": LOOPBACK, "dashboard": False,
                                                   "dashboard_address": f"{LOOPBACK}:0"}}
    cluster = SpecCluster(workers=spec, scheduler=scheduler, silence_logs=level)
    return Client(cluster, direct_to_workers=True)


@contextlib.contextmanager
def connect(workers: int | None = None, scheduler: str | None = None, device: str = "auto", verbose: bool = False):
    """A client for the duration of a ``with`` block: a :func:`local_cluster` of ``workers``
    processes (closed at the end), or the existing cluster at ``scheduler`` (an address such as
    ``tcp://host:8786``; left running)."""
    from distributed import Client

    if (workers is None) == (scheduler is None):
        raise ParameterError("give either workers (a local cluster) or scheduler (an existing cluster), not both")
    if scheduler is not None:
        # the client's own reports (a lost scheduler's reconnection attempts, with tracebacks)
        # only when verbose: a lost scheduler ends in one SchedulerLost line
        quiet = logging.getLogger("distributed")
        before = quiet.level
        quiet.setLevel(logging.INFO if verbose else logging.CRITICAL)
        try:
            try:
                client = Client(scheduler, timeout="10s")
            except OSError as exc:
                raise ParameterError(f"scheduler = {scheduler!r}: cannot connect ({exc})") from None
            except (ValueError, TypeError):  # Dask's parse of the address
                raise ParameterError(f"scheduler = {scheduler!r} is not an address: give one such as "
                                     "tcp://host:8786") from None
            with client:
                yield client
        finally:
            quiet.setLevel(before)
        return
    client = local_cluster(workers, device, verbose)
    try:
        yield client
    finally:
        client.close()
        client.cluster.close()


def saved_specs(checkpoint) -> list[EnsembleSpec]:
    """The specs of the distributed run whose units are in the directory ``checkpoint``."""
    manifest = Path(checkpoint) / MANIFEST
    if not manifest.is_file():
        raise ParameterError(f"{checkpoint}: no {MANIFEST} of a distributed run there to continue from")
    return [EnsembleSpec.from_dict(d) for d in json.loads(manifest.read_text())["specs"]]


def gpu_count() -> int:
    """GPUs visible to this process, without creating a CUDA context in it (workers must start
    theirs after being pinned): from ``CUDA_VISIBLE_DEVICES`` or the NVIDIA driver's device
    nodes."""
    visible = os.environ.get("CUDA_VISIBLE_DEVICES")
    if visible is not None:
        return len([v for v in visible.split(",") if v.strip() not in ("", "-1")])
    return len([p for p in Path("/dev").glob("nvidia[0-9]*")])
