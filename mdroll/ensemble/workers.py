"""Where the stages of a batch run and what they cost: the CPU path's worker threads
(:class:`CpuWorkers`), the clock of the stages (:class:`StageClock`) and the progress bar over
realizations (:func:`progress_bar`); :func:`mdroll.ensemble.pipeline.run_ensemble` drives them."""

from __future__ import annotations

import functools
import threading
import time

from .. import buffers
from ..devices import is_cuda, warp


class CpuWorkers:
    """The CPU path's threads: each part of a batch (:data:`~mdroll.ensemble.pipeline.CPU_CHUNK`
    realizations) is run through lines, force and spectra by the next free one of ``threads``
    Python threads (Warp's CPU launches and FFTW release the GIL; each thread's FFTs take one
    FFTW thread), into arrays the thread keeps from part to part (:mod:`mdroll.buffers`); the
    parts' moments are merged in their order, so the result does not depend on the number of
    threads or on which thread ran which part.

    ``serial`` is a lock that one thread holds at a time: Warp 1.19 keeps the shared memory of a
    CPU tile kernel (the coupled dynamics; the sweep's stream, which only CUDA runs by default)
    behind one pointer per module, so two of them must not run at once (they crashed); the
    decoupled force kernels are plain launches on the CPU. ``loading`` is held through each
    thread's first part: Warp 1.19 loads a module's CPU code at its first launch without a
    lock, and two threads loading the same module at once can free the code the other is
    running (segfaults in the plugin's and the studies' tests, now and then); after one thread's
    first part every module of the path is loaded. Each stage's time is the mean over the
    threads (they overlap), added to ``timings`` by :meth:`add_timings`.
    """

    def __init__(self, threads: int, timings: dict):
        from concurrent.futures import ThreadPoolExecutor

        self.pool = ThreadPoolExecutor(threads) if threads > 1 else None
        self.timings = timings
        self.serial = threading.Lock()
        self.loading = threading.Lock()
        self.local = threading.local()
        self.clocks = []

    def map(self, work, parts):
        """``work(part, clock, serial)`` of each part, in the parts' order, as they finish."""
        run = functools.partial(self._run, work)
        return self.pool.map(run, parts) if self.pool else map(run, parts)

    def _run(self, work, part):
        from ..fft import fftw_threads

        state = self.local.__dict__
        first = not state
        if first:
            state["buffers"] = buffers.Buffers()
            state["clock"] = StageClock("cpu", dict.fromkeys(self.timings, 0.0))
            self.clocks.append(state["clock"])
        with fftw_threads(1), buffers.reused(state["buffers"]):
            if not first:
                return work(part, state["clock"], self.serial)
            with self.loading:
                return work(part, state["clock"], self.serial)

    def add_timings(self) -> None:
        """Add each stage's mean time over the threads since the last call to ``timings``."""
        for name in self.timings:
            self.timings[name] += sum(clock.timings[name] for clock in self.clocks) / max(len(self.clocks), 1)
        for clock in self.clocks:
            clock.timings = dict.fromkeys(self.timings, 0.0)

    def close(self) -> None:
        if self.pool:
            self.pool.shutdown(cancel_futures=True)


class StageClock:
    """Seconds per stage: ``clock(name, fn)`` runs ``fn`` and adds its time to ``timings[name]``.

    On CUDA each stage is bracketed by two events on the device's stream, taken a batch at a
    time (:meth:`take`) and read by :meth:`settle` after the batch's one wait: the host queues a
    stage while the device still runs the one before (synchronizing around every stage would
    leave the device idle through all the host work between launches). A stage's time is then
    the device's, from reaching the stage's first command to finishing its last. On
    the CPU launches are synchronous: wall time.
    """

    def __init__(self, device: str, timings: dict):
        self.device = device
        self.timings = timings
        self.pending = []

    def __call__(self, name: str, fn):
        if not is_cuda(self.device):
            t0 = time.perf_counter()
            out = fn()
            self.timings[name] += time.perf_counter() - t0
            return out
        start = self._event()
        out = fn()
        self.pending.append((name, start, self._event()))
        return out

    def _event(self):
        wp = warp()
        event = wp.Event(self.device, enable_timing=True)
        wp.get_stream(self.device).record_event(event)
        return event

    def take(self) -> list:
        """The stages recorded since the last call, for a later :meth:`settle`."""
        taken, self.pending = self.pending, []
        return taken

    def settle(self, stages: list) -> None:
        """Add the times of ``stages`` (:meth:`take`), waiting for the last of them."""
        wp = warp()
        for name, start, end in stages:
            self.timings[name] += wp.get_event_elapsed_time(start, end) / 1e3


class _NoBar:
    def update(self, n):
        pass

    def close(self):
        pass


def progress_bar(total: int, enabled: bool, desc: str = "realizations"):
    """A tqdm bar over realizations (done, rate, ETA), or a silent stand-in."""
    if not enabled:
        return _NoBar()
    from tqdm.auto import tqdm

    return tqdm(total=total, unit="real", desc=desc, dynamic_ncols=True)
