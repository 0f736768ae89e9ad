"""The ensemble pipeline: lines -> force -> wheel response -> spectra -> running means, batch by batch.

:func:`run_ensemble` composes the parts, each in its own module: the force algorithms
(:mod:`mdroll.forces`), the coupled dynamics (:mod:`.coupled`), the spectra (:mod:`.psd`), batch
sizing (:mod:`.batching`), the accumulated totals and their checkpoint (:mod:`.checkpoint`), the
CPU's worker threads, the stage clock and the progress bar (:mod:`.workers`) and the result
(:mod:`.result`). Here: the arguments' checks and the batch loop.
"""

from __future__ import annotations

import contextlib
import dataclasses
import time
from pathlib import Path

import numpy as np

from ..devices import cpu_cores, is_cuda, queue_on, resolve_device, to_warp, warp
from ..errors import NonFiniteError, ParameterError
from ..kernels.dynamics import INTEGRATORS
from ..kernels.moments import NOT_FINITE
from ..params import Params
from .. import buffers
from ..arguments import check_choice, check_flag, check_integer, check_params
from ..forces.force import launch_force
from ..forces.prepare import prepare_lines
from ..forces.prepared import DEFAULT_LEAF_SIZE
from ..forces.registry import algorithm_entry, coupled_entry, default_algorithm
from ..forces.steps import BOUNDARIES
from .batching import check_batch_fits, check_run_fits, default_batch
from .checkpoint import RunTotals
from .coupled import contact_compliance, coupled_plan, coupled_series
from .lines import add_line, check_seed, parametric_line, realization_indices, rough_lines
from ..roughness.kinds import check_spectrum
from ..roughness.line_grid import from_params, line_rms
from .result import EnsembleResult
from .vibration import with_structures
from .psd import array_rows, psd_moments_of_batch, series_sums, to_host
from .realizations import DEFAULT_REALIZATIONS
from .workers import CpuWorkers, StageClock, progress_bar

MODES = ("decoupled", "coupled")
#: The open-boundary wheel range of an ensemble is set from d0 + H_BOUND_SIGMAS * (the lines' RMS), not from
#: each batch's maximum, so every batch has the same steps. Forces stay exact either way.
H_BOUND_SIGMAS = 6.0
#: With a checkpoint, batches are sized so that one takes about this long (s): a kill loses at
#: most about this much work.
CHECKPOINT_SECONDS = 30.0
#: Realizations a CPU thread runs through the stages at once
#: (:class:`~mdroll.ensemble.workers.CpuWorkers`): few, so that its arrays stay small and are
#: reused (docs/performance.md, CPU).
CPU_CHUNK = 2


def _raise_on_rows(bad_rows: np.ndarray, what: str, stage: str, indices: np.ndarray) -> None:
    """Raise NonFiniteError naming the first realization flagged in ``bad_rows`` (host booleans)."""
    if bad_rows.any():
        row = int(np.argmax(bad_rows))
        raise NonFiniteError(f"{what} is not finite in realization {int(indices[row])} at stage {stage!r}")


def run_ensemble(
    params: Params,
    seed: int = 0,
    realizations=None,
    algorithm: str | None = None,
    mode: str = "decoupled",
    boundary: str = "open",
    device: str = "auto",
    batch: int | None = None,
    progress: bool = True,
    window: bool = True,
    leaf_size: int = DEFAULT_LEAF_SIZE,
    checkpoint=None,
    resume: bool = False,
    memory_limit: int | None = None,
    roughness=None,
    integrator: str = "semi-implicit",
    threads: int | None = None,
    track=None,
    wheel=None,
) -> EnsembleResult:
    """Run an ensemble and return its averaged force and acceleration spectra.

    Realizations (:data:`~mdroll.ensemble.realizations.DEFAULT_REALIZATIONS` when None; an int R
    for 0..R-1, or a sequence of indices) are processed in batches (sized from free device or host memory, capped by
    ``memory_limit`` bytes, in the coupled mode on CUDA without a checkpoint
    planned by its launches' costs: :func:`~mdroll.ensemble.coupled.coupled_plan`; unless
    ``batch`` is given): rough lines (section 3) -> force at d0
    by ``algorithm`` and the wheel on the linearized contact spring (``mode="decoupled"``,
    section 5.1), or the coupled dynamics of eq 13 (``mode="coupled"``; refused for an
    algorithm without a coupled step) -> PSDs (section 6, optional Hann ``window``) -> running
    per-bin mean and variance. Memory stays O(batch x n). ``algorithm``: a registry entry
    (:data:`~mdroll.forces.registry.ALGORITHMS`), by default the mode's
    (:data:`~mdroll.forces.registry.DEFAULT_ALGORITHMS`). ``leaf_size``: springs per tree leaf.

    ``checkpoint``: a file the running accumulators are written to after every batch,
    atomically (temporary file, then rename). With a checkpoint, batches are also sized by
    time: the first holds one realization, each next one as many as the last ran in
    ``CHECKPOINT_SECONDS`` (never more than ``batch``), so that a kill loses at most about that
    much work whatever the batch size. With ``resume=True`` an existing checkpoint of the same
    run is continued where it stopped, with the run's batch size unless ``batch`` or
    ``memory_limit`` is given (a different run is refused, naming the differences); the result
    is the uninterrupted run's to rounding. A line too long for one realization to fit in
    memory is refused before any work (:func:`~mdroll.ensemble.batching.check_run_fits`).

    ``roughness``: a spectrum of :mod:`mdroll.roughness` instead of the one the roughness fields
    of ``params`` name (API only; its description joins the checkpoint's key).

    ``integrator``: the time step of the coupled dynamics, one of
    :data:`~mdroll.kernels.dynamics.INTEGRATORS`; "forward-euler", the thesis's scheme, only with
    ``mode="coupled"`` and only for the coupling study (it grows every oscillation).

    ``threads`` (CPU only; default every core of the process): a batch's realizations go in
    parts of :data:`CPU_CHUNK` through lines, force and spectra, each part on the next free one
    of this many Python threads (Warp's CPU launches and FFTW release the GIL), into memory each
    thread keeps from part to part; the parts' moments are merged in their order, so the spectra
    do not depend on the number of threads at all (:class:`~mdroll.ensemble.workers.CpuWorkers`).
    On CUDA the device runs the batch as a whole.

    Parameters
    ----------
    params : Params
        The physical and numerical parameters, SI units (physics.md section 1).
    seed : int
        Master seed in [0, 2^64); realization j's line depends on (seed, j) alone.
    realizations : None, int or sequence of int
        The run's realizations: R for indices 0..R-1, or the indices themselves; None:
        :data:`~mdroll.ensemble.realizations.DEFAULT_REALIZATIONS`. The result's ``n_real`` is
        their count.
    algorithm : str or None
        Force algorithm (:data:`mdroll.ALGORITHMS`); None: the mode's default.
    mode : {"decoupled", "coupled"}
    boundary : {"open", "periodic"}
    device : str
        ``"auto"``, ``"cpu"``, ``"cuda"`` or ``"cuda:N"``.
    batch : int or None
        Realizations per batch; None: sized from free memory.
    progress : bool
        Show a progress bar.
    window : bool
        Hann window (scaled to mean square 1) before the FFT: the default estimator, free of
        the open record's leakage in every band (docs/physics.md, "The default estimator and
        the resolution flags"); False: the thesis's open, unwindowed record.
    leaf_size : int
        Springs per tree leaf (``algorithm="tree"``).
    checkpoint : path or None
    resume : bool
    memory_limit : int or None
        Bytes the batches may use.
    roughness : RoughnessSpectrum or None
    integrator : str
    threads : int or None
    track, wheel : mdroll.track.Track, mdroll.wheel.Wheel or None
        The rail under the wheel and the wheel (default: the rigid ones, eq 13). Coupled mode
        only: the contact point then moves with the rail's fitted state space (the wheel
        standing above a sleeper) and a modal wheel's modes
        (:func:`mdroll.ensemble.coupled.contact_compliance`); the roughness moves under a
        stationary wheel. A track with ``parametric = True`` adds the moving load's equivalent
        roughness at v0 (:func:`mdroll.ensemble.lines.parametric_line`) to every line. The result
        records them; the wheel and rail vibration spectra follow from the force's
        (:meth:`EnsembleResult.vibration`, :mod:`mdroll.ensemble.vibration`).

    Returns
    -------
    EnsembleResult
        Per bin: ``q`` (rad/m), ``omega = q v0`` (rad/s), ``force_psd`` and its standard error
        (N^2 m: two-sided, per rad/m), ``accel_psd`` and its standard error ((m/s^2)^2 m); and
        ``force_mean``, ``force_rms`` (N), ``n_real``, ``steps``. On a track ``accel_psd`` is the
        wheel's acceleration at the contact, and ``track``, ``wheel`` record the structures.
    """
    # every argument checked here, once
    check_params(params)
    check_spectrum(roughness)
    check_choice("mode", mode, MODES)
    if algorithm is None:
        algorithm = default_algorithm(mode)
    check_choice("integrator", integrator, INTEGRATORS)
    if mode == "decoupled" and integrator != INTEGRATORS[0]:
        raise ParameterError(f"integrator = {integrator!r} is not allowed with mode = 'decoupled': the decoupled "
                             f"response is {INTEGRATORS[0]!r}; use mode = 'coupled'")
    (algorithm_entry if mode == "decoupled" else coupled_entry)(algorithm)
    check_choice("boundary", boundary, BOUNDARIES)
    if wheel is not None:
        wheel.check_run_mass(params.m)
    compliance = contact_compliance(track and track.structure(), wheel)
    if mode == "decoupled" and compliance[0] is not None:
        raise ParameterError("track and wheel other than rigid are not allowed with mode = 'decoupled': "
                             "use mode = 'coupled' (the frequency-domain chain is mdroll.track.linear_chain)")
    seed = check_seed(seed)
    indices = realization_indices(DEFAULT_REALIZATIONS if realizations is None else realizations)
    leaf_size = check_integer("leaf_size", leaf_size, 1, "springs")
    progress, window, resume = (check_flag(name, value) for name, value in
                                (("progress", progress), ("window", window), ("resume", resume)))
    if memory_limit is not None:
        memory_limit = check_integer("memory_limit", memory_limit, 1, "bytes")
    if batch is not None:
        batch = check_integer("batch", batch, 1, "realizations")
    device = resolve_device(device)
    check_run_fits(params, device, memory_limit, mode)
    threads = 1 if is_cuda(device) else (cpu_cores() if threads is None else check_integer("threads", threads, 1, "threads"))

    key = {"params": params.as_dict(), "seed": seed, "realizations": indices.tolist(), "algorithm": algorithm,
           "mode": mode, "boundary": boundary, "window": window, "leaf_size": leaf_size}
    if integrator != INTEGRATORS[0]:
        key["integrator"] = integrator
    if compliance[0] is not None:
        key["track"] = track.key_fields() if track else None
        key["wheel"] = dataclasses.asdict(wheel) if wheel else None
    if roughness is None and params.roughness != "powerlaw":
        roughness = from_params(params)  # read (a table file) once, not per batch
    if roughness is not None:
        key["roughness"] = roughness.describe()
    totals = RunTotals()
    if resume:
        if checkpoint is None or not Path(checkpoint).exists():
            raise ParameterError(f"cannot resume: no checkpoint at {checkpoint!s}")
        totals = RunTotals.load(checkpoint, key)
        if batch is None and memory_limit is None:
            batch = totals.batch
    plan = ()  # the batches' sizes, where a coupled run plans them
    if batch is None:
        batch = default_batch(params, device, memory_limit, wanted=len(indices), mode=mode)
        if mode == "coupled" and checkpoint is None:
            plan = coupled_plan(len(indices), batch, algorithm, compliance[0] is not None, device)
            batch = max(plan)
    totals.batch = int(batch)
    check_batch_fits(params, min(totals.batch, len(indices)), device, mode)
    d0 = params.d0
    excitation = parametric_line(params, track, device)
    h_bound = H_BOUND_SIGMAS * line_rms(params, roughness) + (0.0 if excitation is None else
                                                              float(np.max(np.abs(excitation.numpy()))))
    timings = totals.timings
    bar = progress_bar(len(indices), progress)
    bar.update(totals.done)

    stage = StageClock(device, timings)
    decoupled = mode == "decoupled"

    def series_moments(idx, clock, serial=contextlib.nullcontext()):
        """Lines -> force (and response) -> sums and PSD moments of the realizations ``idx``;
        the coupled response inside ``serial``."""
        lines = clock("generate", lambda: add_line(
            to_warp(rough_lines(params, seed, idx, device=device, roughness=roughness), device), excitation, device))
        prepared = clock("build", lambda: prepare_lines(lines, params, algorithm, boundary, d0, device, leaf_size, h_bound))
        if decoupled:
            out = buffers.empty("force", (len(idx), prepared.steps), warp().float64, device)
            force = clock("force", lambda: launch_force(prepared, params, algorithm, d0, device, out, params.F_N))
            accel = None
        else:
            with serial:
                force, accel = clock("response", lambda: coupled_series(prepared, params, algorithm, device,
                                                                        force_offset=params.F_N,
                                                                        integrator=integrator,
                                                                        compliance=compliance))
        sums = clock("response", lambda: series_sums(force, params, device, decoupled))
        moments = clock("spectra", lambda: psd_moments_of_batch(force, accel, sums, params, device, window))
        return prepared.steps, sums, moments

    rows = None
    start = totals.done
    # with a checkpoint the first batch holds one realization, to time it; a resumed run goes on
    # with the size its last batch planned, so that its batches, and the rounding of their
    # merged moments, are the uninterrupted run's
    size = batch if checkpoint is None else min(batch, totals.next_batch)
    planned = iter(plan)
    workers = None if is_cuda(device) else CpuWorkers(threads, timings)

    def finish(queued: _QueuedBatch) -> None:
        """A queued batch's end on the host, once its copies are there: its stages' times, its
        checks (a failed one ends the run: the moments merged since are never seen or saved) and
        its force sums."""
        if queued.copied is not None:
            warp().synchronize_event(queued.copied)
        stage.settle(queued.stages)
        if workers:
            workers.add_timings()
        for part, host_sums, psd_bad in queued.chunks:
            _raise_on_rows(host_sums[:, NOT_FINITE] > 0, "force", "force" if decoupled else "response", part)
            _raise_on_rows(psd_bad != 0, "force or acceleration PSD", "spectra", part)
        for _, host_sums, _ in queued.chunks:
            totals.add_sums(host_sums, params.F_N)
        totals.largest_batch = max(totals.largest_batch, queued.realizations)
        bar.update(queued.realizations)

    # Without a checkpoint a batch ends on the host while the next one runs on the device: the
    # host queues batch k + 1 before it waits for batch k's copies, so the device never waits
    # for the host between batches. With one, each batch ends before the next begins, so that
    # the file holds checked totals only.
    pending = None
    try:
        while start < len(indices):
            size = next(planned, size)
            began = time.perf_counter()
            idx = indices[start:start + size]
            last = start + len(idx) >= len(indices)
            parts = _cpu_parts(idx, CPU_CHUNK if workers else len(idx))
            outputs = workers.map(series_moments, parts) if workers else [series_moments(idx, stage)]
            chunks = []  # (realizations, sums, PSD flags) of each part, in order, on their way to the host
            with queue_on(device):
                # the parts' moments merged in their order as they come (whichever thread ran them)
                for part, (steps, sums, (force_moments, accel_moments, psd_not_finite)) in zip(parts, outputs):
                    totals.steps = steps
                    stage("spectra", lambda: totals.add_moments(len(part), force_moments, accel_moments))
                    chunks.append((part, to_host(array_rows(sums, device), page_locked=True, wait=False),
                                   to_host(psd_not_finite, page_locked=True, wait=False)))
                if last:
                    # the result, queued before the last batch's copies are waited for
                    rows = totals.spectra_on_host(params, wait=False)
            queued = _QueuedBatch(len(idx), chunks, stage.take(), _copies_done(device))
            del outputs
            if pending is not None:
                finish(pending)
            if checkpoint is None:
                pending = queued
            else:
                finish(queued)
                # the next batch: what this one's rate does in CHECKPOINT_SECONDS, within the memory's batch
                rate = len(idx) / max(time.perf_counter() - began, 1e-9)
                size = totals.next_batch = int(min(batch, max(1, rate * CHECKPOINT_SECONDS)))
                totals.save(checkpoint, key)
            start += len(idx)
        if pending is not None:
            finish(pending)
    finally:
        if workers:
            workers.close()
    bar.close()

    if rows is None:  # a resumed run that had nothing left to do
        with queue_on(device):
            rows = totals.spectra_on_host(params)
    q, omega, force_psd, force_psd_stderr, accel_psd, accel_psd_stderr = rows
    n = len(indices)
    result = EnsembleResult(
        q=q, omega=omega, force_psd=force_psd, force_psd_stderr=force_psd_stderr, accel_psd=accel_psd,
        accel_psd_stderr=accel_psd_stderr, n_real=n, params=params, seed=seed, algorithm=algorithm,
        mode=mode, boundary=boundary, device=device, steps=totals.steps, force_mean=totals.force_mean_sum / n,
        force_rms=totals.force_rms_sum / n, contact_lost_steps=totals.lost, timings=timings,
        batch=totals.largest_batch, realizations=indices.tolist(), window=bool(window),
    )
    return with_structures(result, track, wheel)


@dataclasses.dataclass
class _QueuedBatch:
    """A batch whose work is queued: its realizations' count, each part's ``(realizations,
    sums, PSD flags)`` with the host copies of the last two on their way, its stages' events
    (:meth:`~mdroll.ensemble.workers.StageClock.take`) and the event after its copies (None on
    the CPU, where they are there at once)."""

    realizations: int
    chunks: list
    stages: list
    copied: object


def _copies_done(device: str):
    """An event on ``device``'s stream after the work queued so far (None on the CPU)."""
    if not is_cuda(device):
        return None
    wp = warp()
    event = wp.Event(device)
    wp.get_stream(device).record_event(event)
    return event


def _cpu_parts(idx: np.ndarray, size: int) -> list[np.ndarray]:
    """``idx`` in consecutive parts of ``size`` realizations (the last may be shorter)."""
    return [idx[i:i + size] for i in range(0, len(idx), size)]
