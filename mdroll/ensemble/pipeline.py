"""The ensemble pipeline: lines -> force -> wheel response -> spectra -> running means, batch by batch."""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..devices import is_cuda, queue_on, resolve_device, to_warp, warp
from ..params import ParameterError, Params
from .force import ALGORITHMS, BOUNDARIES, DEFAULT_LEAF_SIZE, check_choice, launch_force, prepare_lines
from .lines import check_seed, realization_indices, rough_lines
from ..kernels.spectra import LOST, NOT_FINITE, SUM_DEVIATION, SUM_SQUARES
from .spectra import RunningMoments, array_module, psd_moments_of_batch, series_sums, to_host, wavenumbers

MODES = ("decoupled", "coupled")
#: The open-boundary wheel range of an ensemble is set from d0 + H_BOUND_SIGMAS * h0, not from
#: each batch's maximum, so every batch has the same steps. Forces stay exact either way.
H_BOUND_SIGMAS = 6.0
#: Bytes of device memory per spring of one realization in a batch (lines, half spectrum,
#: prefix sums, tree, force, acceleration and FFT work space), for sizing batches.
BYTES_PER_POINT = 96
STAGES = ("generate", "build", "force", "response", "spectra")


class NonFiniteError(FloatingPointError):
    """NaN or infinity in a force or spectrum; the message names the realization and stage."""


@dataclass
class EnsembleResult:
    """Ensemble-averaged force and acceleration spectra (physics.md section 6).

    Attributes
    ----------
    q : (K,) wavenumbers q_k = 2 pi k / (S dx), rad/m.
    omega : (K,) angular frequencies q v0, rad/s.
    force_psd, force_psd_stderr : (K,) mean two-sided PSD of F over the ensemble and its standard
        error, N^2 m (per rad/m; divide by v0 for per rad/s).
    accel_psd, accel_psd_stderr : (K,) the same for the acceleration, (m/s^2)^2 m.
    force_rms : RMS of F - mean F averaged over realizations, N.
    force_mean : mean force, N.
    contact_lost_steps : steps with F = 0 (the wheel off the rail) summed over the ensemble.
    timings : seconds per stage ("generate", "build", "force", "response", "spectra"): on CUDA
        the device's time, from CUDA events around each stage; on the CPU wall time.
    batch : realizations per batch; realizations : the realization indices, in order.
    """

    q: np.ndarray
    omega: np.ndarray
    force_psd: np.ndarray
    force_psd_stderr: np.ndarray
    accel_psd: np.ndarray
    accel_psd_stderr: np.ndarray
    n_real: int
    params: Params
    seed: int
    algorithm: str
    mode: str
    boundary: str
    device: str
    steps: int
    force_mean: float
    force_rms: float
    contact_lost_steps: int = 0
    timings: dict = field(default_factory=dict)
    batch: int = 0
    realizations: list = field(default_factory=list)

    def save(self, path) -> Path:
        """Write an ``.npz`` with the spectra, the parameters and the provenance."""
        path = Path(path)
        meta = {
            "params": self.params.as_dict(),
            **{k: getattr(self, k) for k in ("n_real", "seed", "algorithm", "mode", "boundary", "device", "steps",
                                               "force_mean", "force_rms", "contact_lost_steps", "timings", "batch",
                                               "realizations")},
        }
        from .. import __version__

        meta["mdroll_version"] = __version__
        np.savez(path, q=self.q, omega=self.omega, force_psd=self.force_psd, force_psd_stderr=self.force_psd_stderr,
                 accel_psd=self.accel_psd, accel_psd_stderr=self.accel_psd_stderr, meta=json.dumps(meta))
        return path

    @classmethod
    def load(cls, path) -> "EnsembleResult":
        with np.load(path) as data:
            meta = json.loads(str(data["meta"]))
            arrays = {k: data[k] for k in ("q", "omega", "force_psd", "force_psd_stderr", "accel_psd", "accel_psd_stderr")}
        meta.pop("mdroll_version", None)
        return cls(params=Params(**meta.pop("params")), **arrays, **meta)

    @classmethod
    def merge(cls, results: list["EnsembleResult"]) -> "EnsembleResult":
        """One result from ensembles of disjoint realizations of the same run (say, one per
        process): per-bin means and variances merged exactly (Chan et al.)."""
        first = results[0]
        same = ("params", "seed", "algorithm", "mode", "boundary", "steps")
        for other in results[1:]:
            differ = [k for k in same if getattr(other, k) != getattr(first, k)]
            if differ:
                raise ParameterError(f"cannot merge results that differ in {differ}")
        indices = [i for r in results for i in r.realizations]
        if len(set(indices)) != len(indices):
            raise ParameterError("cannot merge results that share realizations (each would count twice)")
        moments = {}
        for name in ("force_psd", "accel_psd"):
            m = RunningMoments(first.q.size)
            for r in results:
                err = getattr(r, name + "_stderr")
                m.merge(r.n_real, getattr(r, name), err**2 * r.n_real * (r.n_real - 1))
            moments[name] = m
        n = sum(r.n_real for r in results)
        return cls(
            q=first.q, omega=first.omega, force_psd=moments["force_psd"].mean, force_psd_stderr=moments["force_psd"].stderr,
            accel_psd=moments["accel_psd"].mean, accel_psd_stderr=moments["accel_psd"].stderr, n_real=n,
            params=first.params, seed=first.seed, algorithm=first.algorithm, mode=first.mode, boundary=first.boundary,
            device=",".join(sorted({r.device for r in results})), steps=first.steps,
            force_mean=sum(r.force_mean * r.n_real for r in results) / n,
            force_rms=sum(r.force_rms * r.n_real for r in results) / n,
            contact_lost_steps=sum(r.contact_lost_steps for r in results),
            timings={k: sum(r.timings.get(k, 0.0) for r in results) for k in STAGES}, batch=first.batch,
            realizations=indices,
        )

    def plot(self, quantity: str = "accel", path=None, ax=None):
        """Log-log ensemble mean PSD on omega with its standard-error band, in the style of the
        thesis's Figure 2: omega_0, q_min v0, the q^-(2H+3) slope and the eq 40 curve marked."""
        from ..plotting import plot_psd

        return plot_psd(self, quantity, path=path, ax=ax)


def default_batch(params: Params, device: str, memory_limit: int | None = None, wanted: int | None = None) -> int:
    """Realizations per batch that fit in half the free memory of the device (host RAM on CPU),
    or in half of ``memory_limit`` bytes when that is smaller.

    On CUDA, memory that Warp's and CuPy's pools keep from earlier work counts as used by the
    driver; when that would split a run of ``wanted`` realizations, the pools hand their unused
    memory back first and the device is measured again (a run after larger ones would
    otherwise go in several batches: 2x the time of the coupled dynamics at 300 x 2^20).
    """
    per_realization = BYTES_PER_POINT * params.n_points

    def fitting(free: int) -> int:
        if memory_limit is not None:
            free = min(free, memory_limit)
        return max(1, int(0.5 * free // per_realization))

    if not device.startswith("cuda"):
        return fitting(_host_available_bytes())
    wp = warp()
    batch = fitting(wp.get_device(device).free_memory)
    if wanted is not None and batch < wanted:
        _release_pools(device)
        batch = fitting(wp.get_device(device).free_memory)
    return batch


def _release_pools(device: str) -> None:
    """Return the unused memory of CuPy's pool and of Warp's stream-ordered pool to the driver
    (Warp's pool trims to its release threshold at a synchronization)."""
    import sys

    wp = warp()
    if "cupy" in sys.modules:
        sys.modules["cupy"].get_default_memory_pool().free_all_blocks()
    if wp.is_mempool_supported(device) and wp.is_mempool_enabled(device):
        threshold = wp.get_mempool_release_threshold(device)
        wp.set_mempool_release_threshold(device, 0)
        wp.synchronize_device(device)
        wp.set_mempool_release_threshold(device, threshold)


def _host_available_bytes() -> int:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 4 * 2**30


def _raise_on_rows(bad_rows: np.ndarray, what: str, stage: str, indices: np.ndarray) -> None:
    """Raise NonFiniteError naming the first realization flagged in ``bad_rows`` (host booleans)."""
    if bad_rows.any():
        row = int(np.argmax(bad_rows))
        raise NonFiniteError(f"{what} is not finite in realization {int(indices[row])} at stage {stage!r}")


CHECKPOINT = "checkpoint.npz"


def run_ensemble(
    params: Params,
    seed: int = 0,
    realizations=None,
    algorithm: str = "tree",
    mode: str = "decoupled",
    boundary: str = "open",
    device: str = "auto",
    batch: int | None = None,
    progress: bool = True,
    window: bool = False,
    leaf_size: int = DEFAULT_LEAF_SIZE,
    checkpoint=None,
    resume: bool = False,
    memory_limit: int | None = None,
) -> EnsembleResult:
    """Run an ensemble and return its averaged force and acceleration spectra.

    Realizations (``params.n_real`` when None; an int R for 0..R-1, or a sequence of indices)
    are processed in batches (sized from free device or host memory, capped by
    ``memory_limit`` bytes, unless ``batch`` is given): rough lines (section 3) -> force at d0
    by ``algorithm`` and the wheel on the linearized contact spring (``mode="decoupled"``,
    section 5.1), or the coupled dynamics of eq 13 (``mode="coupled"``) -> PSDs (section 6,
    optional Hann ``window``) -> running per-bin mean and variance. Memory stays O(batch x n).

    ``checkpoint``: a file the running accumulators are written to after every batch,
    atomically (temporary file, then rename). With ``resume=True`` an existing checkpoint of
    the same run is continued where it stopped (a different run is refused, naming the
    differences); the result is the uninterrupted run's to rounding.
    """
    check_choice("algorithm", algorithm, ALGORITHMS)
    check_choice("mode", mode, MODES)
    check_choice("boundary", boundary, BOUNDARIES)
    seed = check_seed(seed)
    indices = realization_indices(params.n_real if realizations is None else realizations)
    device = resolve_device(device)
    if memory_limit is not None and (isinstance(memory_limit, bool) or not isinstance(memory_limit, (int, np.integer))
                                     or memory_limit < 1):
        raise ParameterError(f"memory_limit = {memory_limit!r} is not allowed: it must be a positive number of bytes")
    if batch is None:
        batch = default_batch(params, device, memory_limit, wanted=len(indices))
    if isinstance(batch, bool) or not isinstance(batch, (int, np.integer)) or batch < 1:
        raise ParameterError(f"batch = {batch!r} is not allowed: it must be a positive integer")

    key = {"params": params.as_dict(), "seed": seed, "realizations": indices.tolist(), "algorithm": algorithm,
           "mode": mode, "boundary": boundary, "window": window, "leaf_size": leaf_size}
    totals = _Totals()
    if resume:
        if checkpoint is None or not Path(checkpoint).exists():
            raise ParameterError(f"cannot resume: no checkpoint at {checkpoint!s}")
        totals = _Totals.load(checkpoint, key)
    d0 = params.d0
    h_bound = H_BOUND_SIGMAS * params.h0
    timings = totals.timings
    bar = progress_bar(len(indices), progress)
    bar.update(totals.done)

    stage = _StageClock(device, timings)
    rows = None
    for start in range(totals.done, len(indices), batch):
        idx = indices[start:start + batch]
        lines = stage("generate", lambda: to_warp(rough_lines(params, seed, idx, device=device), device))
        prepared = stage("build", lambda: prepare_lines(lines, params, algorithm, boundary, d0, device, leaf_size, h_bound))
        totals.steps = prepared.steps
        decoupled = mode == "decoupled"
        if decoupled:
            force = stage("force", lambda: launch_force(prepared, params, algorithm, d0, device, offset=params.F_N))
            accel = None
        else:
            force, accel = stage("response", lambda: coupled_series(prepared, params, algorithm, device,
                                                                    force_offset=params.F_N))
        sums = stage("response", lambda: series_sums(force, params, device, decoupled))
        force_moments, accel_moments, psd_not_finite = stage(
            "spectra", lambda: psd_moments_of_batch(force, accel, sums, params, device, window))
        with queue_on(device):
            stage("spectra", lambda: totals.add_moments(len(idx), force_moments, accel_moments))
            if start + batch >= len(indices):
                # the result, queued before the last batch's wait, which then covers its copy too
                rows = totals.spectra_on_host(params, wait=False)
        # the batch's one wait: its checks and force sums need the sums and flags on the host (a
        # failed check ends the run: the moments just merged are never seen or saved)
        host_sums, psd_bad = to_host(sums), to_host(psd_not_finite)
        stage.settle()
        _raise_on_rows(host_sums[:, NOT_FINITE] > 0, "force", "force" if decoupled else "response", idx)
        _raise_on_rows(psd_bad != 0, "force or acceleration PSD", "spectra", idx)
        totals.add_sums(host_sums, params.F_N)
        if checkpoint is not None:
            totals.save(checkpoint, key)
        bar.update(len(idx))
        del lines, prepared, force, accel
    bar.close()

    if rows is None:  # a resumed run that had nothing left to do
        with queue_on(device):
            rows = totals.spectra_on_host(params)
    q, omega, force_psd, force_psd_stderr, accel_psd, accel_psd_stderr = rows
    stage.settle()
    n = len(indices)
    return EnsembleResult(
        q=q, omega=omega, force_psd=force_psd, force_psd_stderr=force_psd_stderr, accel_psd=accel_psd,
        accel_psd_stderr=accel_psd_stderr, n_real=n, params=params, seed=seed, algorithm=algorithm, mode=mode, boundary=boundary,
        device=device, steps=totals.steps, force_mean=totals.force_mean_sum / n, force_rms=totals.force_rms_sum / n,
        contact_lost_steps=totals.lost, timings=timings, batch=int(batch), realizations=indices.tolist(),
    )


class _StageClock:
    """Seconds per stage: ``clock(name, fn)`` runs ``fn`` and adds its time to ``timings[name]``.

    On CUDA each stage is bracketed by two events on the device's stream, read by :meth:`settle`
    after the batch's one wait: the host queues a stage while the device still runs the one
    before. (Synchronizing around every stage, as before, left the device idle through all the
    host work between launches: ~2 ms of a 25 ms thesis-scale run on an H200.) A stage's time
    is then the device's, from reaching the stage's first command to finishing its last. On
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

    def settle(self) -> None:
        """Add the recorded stages' times (waits for the last of them)."""
        wp = warp()
        for name, start, end in self.pending:
            self.timings[name] += wp.get_event_elapsed_time(start, end) / 1e3
        self.pending.clear()


@dataclass
class _Totals:
    """What a run has accumulated: PSD moments, force sums, contact-loss count, timings, and how
    many realizations (from the start of the list) are done."""

    force: RunningMoments | None = None
    accel: RunningMoments | None = None
    done: int = 0
    steps: int | None = None
    force_mean_sum: float = 0.0
    force_rms_sum: float = 0.0
    lost: int = 0
    timings: dict = field(default_factory=lambda: dict.fromkeys(STAGES, 0.0))

    def add_moments(self, rows: int, force_moments, accel_moments) -> None:
        """Merge a batch's PSD moments (:func:`psd_moments_of_batch`) of ``rows`` realizations,
        where they are (queued on the device: nothing waits)."""
        xp = array_module(force_moments)
        if self.force is None:
            bins = force_moments.shape[0]
            self.force, self.accel = RunningMoments(bins, xp), RunningMoments(bins, xp)
        else:  # a resumed run's moments come from the host: continue where the batches are
            self.force.move_to(xp)
            self.accel.move_to(xp)
        self.force.add_moments(rows, force_moments)
        self.accel.add_moments(rows, accel_moments)

    def add_sums(self, sums: np.ndarray, F_N: float) -> None:
        """Add a batch's force sums (host rows of :func:`series_sums`: deviations from ``F_N``,
        N) and count its realizations done."""
        mean_deviation = sums[:, SUM_DEVIATION] / self.steps
        variance = np.maximum(sums[:, SUM_SQUARES] / self.steps - mean_deviation**2, 0.0)
        self.force_mean_sum += float(np.sum(F_N + mean_deviation))
        self.force_rms_sum += float(np.sum(np.sqrt(variance)))
        self.lost += int(sums[:, LOST].sum())
        self.done += sums.shape[0]

    def spectra_on_host(self, params: Params, wait: bool = True) -> tuple[np.ndarray, ...]:
        """``(q, omega, force mean, its stderr, accel mean, its stderr)`` per bin (rad/m, rad/s,
        N^2 m, N^2 m, (m/s^2)^2 m, (m/s^2)^2 m), computed where the moments live and brought to
        the host in one copy, into page-locked memory on CUDA (the rows are views of it): six
        separate copies and host arithmetic on 5e5 bins took ~10 ms of a 30 ms thesis-scale run
        on an H200 (benchmarks/results/host_probe_H200.json), one copy into pageable memory ~3
        (overhead_probe_H200_v7.json). ``wait=False``: the copy is only queued (:func:`to_host`)."""
        force_mean, force_stderr = self.force.mean_and_stderr()
        accel_mean, accel_stderr = self.accel.mean_and_stderr()
        xp = array_module(force_mean)
        q = wavenumbers(self.steps, params.dx, xp)
        return tuple(to_host(xp.stack([q, q * params.v0, force_mean, force_stderr, accel_mean, accel_stderr]),
                             page_locked=True, wait=wait))

    def save(self, path, key: dict) -> None:
        """Write the totals and the run's identity ``key`` to ``path`` atomically."""
        from .. import __version__

        path = Path(path)
        meta = {**key, "done": self.done, "steps": self.steps, "force_mean_sum": self.force_mean_sum,
                "force_rms_sum": self.force_rms_sum, "lost": self.lost, "timings": self.timings, "count": self.force.count,
                "versions": {"mdroll": __version__, "warp": warp().config.version, "numpy": np.__version__}}
        tmp = path.with_name(path.name + ".tmp")
        with open(tmp, "wb") as f:
            np.savez(f, meta=json.dumps(meta), force_mean=self.force.mean, force_m2=self.force.m2,
                     accel_mean=self.accel.mean, accel_m2=self.accel.m2)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)

    @classmethod
    def load(cls, path, key: dict) -> "_Totals":
        """The totals saved at ``path``; refuses a checkpoint of a different run, naming what differs."""
        meta, arrays = read_checkpoint(path)
        differences = [f"{k}: {meta['params'][k]!r} (checkpoint) vs {v!r} (now)"
                       for k, v in key["params"].items() if meta["params"].get(k) != v]
        differences += [f"{k}: {_short(meta.get(k))} (checkpoint) vs {_short(v)} (now)"
                        for k, v in key.items() if k != "params" and meta.get(k) != v]
        if differences:
            raise ParameterError(f"cannot resume {path}: the run differs from the checkpoint: " + "; ".join(differences))
        totals = cls(done=meta["done"], steps=meta["steps"], force_mean_sum=meta["force_mean_sum"],
                     force_rms_sum=meta["force_rms_sum"], lost=meta["lost"], timings=meta["timings"])
        totals.force, totals.accel = RunningMoments(arrays["force_mean"].size), RunningMoments(arrays["accel_mean"].size)
        totals.force.merge(meta["count"], arrays["force_mean"], arrays["force_m2"])
        totals.accel.merge(meta["count"], arrays["accel_mean"], arrays["accel_m2"])
        return totals


def read_checkpoint(path) -> tuple[dict, dict]:
    """The metadata (run identity, progress, versions) and the accumulator arrays of a checkpoint."""
    with np.load(path) as data:
        return json.loads(str(data["meta"])), {k: data[k] for k in data.files if k != "meta"}


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def coupled_series(prepared, params: Params, algorithm: str, device: str, d_start: float | None = None,
                   force_offset: float = 0.0):
    """Force (N, less ``force_offset``) and acceleration d'' (m/s^2) series of eq 13 for
    prepared lines; the wheel starts at indentation ``d_start`` (default d0) at rest. Contact is
    lost where F = 0."""
    from ..kernels.dynamics import COUPLED_LANES, DIRECT, EDGE, TREE, coupled_response

    wp = warp()
    rows = prepared.lines.shape[0]
    force = wp.empty((rows, prepared.steps), dtype=wp.float64, device=device)
    accel = wp.empty_like(force)
    empty_tree = wp.empty((rows, 1), dtype=wp.vec2d, device=device)
    empty_prefix = wp.empty((rows, 1), dtype=wp.float64, device=device)
    code = {"direct": DIRECT, "tree": TREE, "edge": EDGE}[algorithm]
    wp.launch_tiled(
        coupled_response,
        dim=[rows],
        block_dim=COUPLED_LANES,
        inputs=[code, prepared.lines,
                prepared.prefix if prepared.prefix is not None else empty_prefix,
                prepared.tree if prepared.tree is not None else empty_tree,
                prepared.level_offsets if prepared.level_offsets is not None else wp.zeros(1, dtype=wp.int32, device=device),
                prepared.bounds if prepared.bounds is not None else wp.empty(1, dtype=wp.vec2d, device=device),
                prepared.top_level, prepared.leaf_size, prepared.n_work, prepared.first, prepared.steps,
                params.d0 if d_start is None else d_start, params.dx, params.R, params.E_star, params.F_N, 1.0 / params.m, params.dt, force_offset, force, accel],
        device=device,
    )
    return force, accel


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


def result_summary(result: EnsembleResult) -> dict:
    """JSON-ready summary: parameters, derived values, RMS force, timings, device."""
    p = result.params
    return {
        "params": p.as_dict(),
        "derived": {k: {"value": v, "unit": u} for k, (v, u, _) in p.derived().items()},
        "n_real": result.n_real, "seed": result.seed, "algorithm": result.algorithm, "mode": result.mode,
        "boundary": result.boundary, "device": result.device, "steps": result.steps,
        "force_mean_N": result.force_mean, "force_rms_N": result.force_rms,
        "contact_lost_steps": result.contact_lost_steps,
        "timings_s": result.timings,
    }


