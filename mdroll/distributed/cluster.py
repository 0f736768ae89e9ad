"""Clients for :class:`~mdroll.distributed.DaskRunner`: a local cluster of pinned workers, or an
existing cluster's scheduler."""

from __future__ import annotations

import contextlib
import logging
import os
from pathlib import Path

from ..devices import cpu_cores
from ..errors import ParameterError

# Dask's ``distributed`` is an optional dependency (the ``distributed`` extra): the functions that
# need it import it, so that this module imports without it.

#: A local cluster listens on the loopback interface only: it serves no one outside this machine.
LOOPBACK = "127.0.0.1"
#: Dask settings of a local cluster's workers: no statistical profiler, whose thread would take
#: the interpreter every few milliseconds from the unit's thread, which launches the device's work
#: (it feeds the dashboard, which a local cluster does not start).
QUIET_WORKER = {"distributed.worker.profile.enabled": False}


def local_cluster(workers: int, device: str = "auto", verbose: bool = False):
    """A ``dask.distributed.Client`` on a cluster of ``workers`` processes on this machine.

    ``device`` ``"cpu"``: processes of one thread each, at most one per core. A CUDA device (or
    ``"auto"`` where GPUs are present): one process per GPU, ``workers`` at most the number of
    GPUs, each pinned to its GPU by ``CUDA_VISIBLE_DEVICES`` before Warp starts in it (so each
    worker's ``cuda:0`` is its own GPU). ``dask-cuda``'s ``LocalCUDACluster`` does the same; this
    spec needs only ``distributed``. The client takes the units' parts from the workers directly,
    not through the scheduler (one hop, not two: the workers are on this machine), and the workers
    run without Dask's profiler (:data:`QUIET_WORKER`). Dask's logs below warnings are shown only
    when ``verbose``.
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
                                                          "silence_logs": level, "config": QUIET_WORKER}}
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


def gpu_count() -> int:
    """GPUs visible to this process, without creating a CUDA context in it (workers must start
    theirs after being pinned): from ``CUDA_VISIBLE_DEVICES`` or the NVIDIA driver's device
    nodes."""
    visible = os.environ.get("CUDA_VISIBLE_DEVICES")
    if visible is not None:
        return len([v for v in visible.split(",") if v.strip() not in ("", "-1")])
    return len([p for p in Path("/dev").glob("nvidia[0-9]*")])
