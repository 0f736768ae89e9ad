"""The ensemble pipeline: lines -> force -> wheel response -> spectra -> running means, batch by batch."""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..devices import resolve_device, synchronize, warp
from ..params import ParameterError, Params
from .force import ALGORITHMS, BOUNDARIES, check_choice, launch_force, prepare_lines
from .lines import check_seed, realization_indices, rough_lines
from .spectra import RunningMoments, array_module, array_rows, psd_rows, to_host, wavenumbers

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
    contact_lost_steps : steps with F = 0 summed over the ensemble (coupled mode).
    timings : seconds per stage ("generate", "build", "force", "response", "spectra").
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

    def save(self, path) -> Path:
        """Write an ``.npz`` with the spectra, the parameters and the provenance."""
        path = Path(path)
        meta = {
            "params": self.params.as_dict(),
            **{k: getattr(self, k) for k in ("n_real", "seed", "algorithm", "mode", "boundary", "device", "steps",
                                               "force_mean", "force_rms", "contact_lost_steps", "timings")},
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

    def plot(self, quantity: str = "accel", path=None, ax=None):
        """Log-log ensemble mean PSD on omega with its standard-error band, in the style of the
        thesis's Figure 2: omega_0, q_min v0, the q^-(2H+3) slope and the eq 40 curve marked."""
        from ..plotting import plot_psd

        return plot_psd(self, quantity, path=path, ax=ax)


def default_batch(params: Params, device: str) -> int:
    """Realizations per batch that fit in half the free memory of the device (host RAM on CPU)."""
    wp = warp()
    if device.startswith("cuda"):
        free = wp.get_device(device).free_memory
    else:
        free = _host_available_bytes()
    per_realization = BYTES_PER_POINT * params.n_points
    return max(1, int(0.5 * free // per_realization))


def _host_available_bytes() -> int:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 4 * 2**30


def _check_finite(values, what: str, stage: str, indices: np.ndarray) -> None:
    """Raise NonFiniteError naming the first realization whose row holds NaN or infinity."""
    xp = array_module(values)
    finite_rows = xp.isfinite(values).all(axis=1)
    if not bool(finite_rows.all()):
        row = int(np.argmin(to_host(finite_rows)))
        raise NonFiniteError(f"{what} is not finite in realization {int(indices[row])} at stage {stage!r}")


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
    leaf_size: int = 8,
) -> EnsembleResult:
    """Run an ensemble and return its averaged force and acceleration spectra.

    Realizations (``params.n_real`` when None; an int R for 0..R-1, or a sequence of indices)
    are processed in batches (sized from free device or host memory unless ``batch`` is given):
    rough lines (section 3) -> force at d0 by ``algorithm`` and the wheel on the linearized
    contact spring (``mode="decoupled"``, section 5.1), or the coupled dynamics of eq 13
    (``mode="coupled"``) -> PSDs (section 6, optional Hann ``window``) -> running per-bin mean
    and variance. Memory stays O(batch x n).
    """
    wp = warp()
    check_choice("algorithm", algorithm, ALGORITHMS)
    check_choice("mode", mode, MODES)
    check_choice("boundary", boundary, BOUNDARIES)
    seed = check_seed(seed)
    indices = realization_indices(params.n_real if realizations is None else realizations)
    device = resolve_device(device)
    if batch is None:
        batch = default_batch(params, device)
    if isinstance(batch, bool) or not isinstance(batch, (int, np.integer)) or batch < 1:
        raise ParameterError(f"batch = {batch!r} is not allowed: it must be a positive integer")

    d0 = params.d0
    h_bound = H_BOUND_SIGMAS * params.h0
    timings = dict.fromkeys(STAGES, 0.0)
    force_moments = accel_moments = None
    force_mean_sum = force_rms_sum = 0.0
    lost_total = 0
    steps = None
    bar = progress_bar(len(indices), progress)

    def stage(name, fn):
        synchronize(device)
        t0 = time.perf_counter()
        out = fn()
        synchronize(device)
        timings[name] += time.perf_counter() - t0
        return out

    for start in range(0, len(indices), batch):
        idx = indices[start:start + batch]
        lines = stage("generate", lambda: rough_lines(params, seed, idx, device=device))
        if not isinstance(lines, wp.array):
            lines = wp.array(lines, dtype=wp.float64, device="cpu", copy=False)
        prepared = stage("build", lambda: prepare_lines(lines, params, algorithm, boundary, d0, device, leaf_size, h_bound))
        steps = prepared.steps
        if mode == "decoupled":
            force = stage("force", lambda: launch_force(prepared, params, algorithm, d0, device))
            accel = stage("response", lambda: _decoupled(force, params, device))
        else:
            force, accel, lost = stage("response", lambda: coupled_series(prepared, params, algorithm, device))
            lost_total += lost
        force_rows = array_rows(force, device)
        _check_finite(force_rows, "force", "force" if mode == "decoupled" else "response", idx)
        force_psd = stage("spectra", lambda: psd_rows(force, params.dx, device, window))
        accel_psd = stage("spectra", lambda: psd_rows(accel, params.dx, device, window))
        _check_finite(force_psd, "force PSD", "spectra", idx)
        _check_finite(accel_psd, "acceleration PSD", "spectra", idx)
        if force_moments is None:
            xp = array_module(force_psd)
            force_moments = RunningMoments(force_psd.shape[1], xp)
            accel_moments = RunningMoments(accel_psd.shape[1], xp)
        stage("spectra", lambda: (force_moments.add(force_psd), accel_moments.add(accel_psd)))
        force_mean_sum += float(force_rows.mean(axis=1).sum())
        force_rms_sum += float(force_rows.std(axis=1).sum())
        bar.update(len(idx))
        del lines, prepared, force, accel
    bar.close()

    q = wavenumbers(steps, params.dx)
    return EnsembleResult(
        q=q, omega=q * params.v0,
        force_psd=force_moments.mean, force_psd_stderr=force_moments.stderr,
        accel_psd=accel_moments.mean, accel_psd_stderr=accel_moments.stderr,
        n_real=len(indices), params=params, seed=seed, algorithm=algorithm, mode=mode, boundary=boundary,
        device=device, steps=steps, force_mean=force_mean_sum / len(indices), force_rms=force_rms_sum / len(indices),
        contact_lost_steps=lost_total, timings=timings,
    )


#: Steps per chunk of the parallel decoupled response.
RESPONSE_CHUNK = 256


def euler_transfer(params: Params, steps: int) -> np.ndarray:
    """The 2x2 matrix that carries (y, y') over ``steps`` free semi-implicit Euler steps of
    ``m y'' = -k_c y``: one step is ``[[1 - dt^2 w^2, dt], [-dt w^2, 1]]`` with w^2 = k_c / m."""
    dt, w2 = params.dt, params.k_contact / params.m
    one_step = np.array([[1.0 - dt * dt * w2, dt], [-dt * w2, 1.0]])
    return np.linalg.matrix_power(one_step, steps)


def _decoupled(force, params: Params, device: str):
    """Acceleration (m/s^2) of the wheel on the linearized contact spring (section 5.1)."""
    from ..kernels.dynamics import decoupled_chunk_ends, decoupled_chunk_starts, decoupled_chunks

    wp = warp()
    rows, steps = force.shape
    chunks = -(-steps // RESPONSE_CHUNK)
    ends = wp.empty((rows, chunks), dtype=wp.vec2d, device=device)
    starts = wp.empty_like(ends)
    accel = wp.empty(force.shape, dtype=wp.float64, device=device)
    common = [params.F_N, params.k_contact, 1.0 / params.m, params.dt]
    wp.launch(decoupled_chunk_ends, dim=(rows, chunks), inputs=[force, steps, RESPONSE_CHUNK, *common, ends], device=device)
    transfer = wp.mat22d(*euler_transfer(params, RESPONSE_CHUNK).ravel())
    wp.launch(decoupled_chunk_starts, dim=rows, inputs=[ends, chunks, transfer, starts], device=device)
    wp.launch(decoupled_chunks, dim=(rows, chunks), inputs=[force, steps, RESPONSE_CHUNK, starts, *common, accel],
              device=device)
    return accel


def coupled_series(prepared, params: Params, algorithm: str, device: str, d_start: float | None = None):
    """Force (N) and acceleration d'' (m/s^2) series of eq 13 for prepared lines, and the number
    of steps without contact; the wheel starts at indentation ``d_start`` (default d0) at rest."""
    from ..kernels.dynamics import DIRECT, EDGE, TREE, coupled_response

    wp = warp()
    rows = prepared.lines.shape[0]
    force = wp.empty((rows, prepared.steps), dtype=wp.float64, device=device)
    accel = wp.empty_like(force)
    lost = wp.zeros(rows, dtype=wp.int32, device=device)
    empty_tree = wp.empty((rows, 1), dtype=wp.vec2d, device=device)
    empty_prefix = wp.empty((rows, 1), dtype=wp.float64, device=device)
    code = {"direct": DIRECT, "tree": TREE, "edge": EDGE}[algorithm]
    wp.launch(
        coupled_response,
        dim=rows,
        inputs=[code, prepared.lines,
                prepared.prefix if prepared.prefix is not None else empty_prefix,
                prepared.tree if prepared.tree is not None else empty_tree,
                prepared.level_offsets if prepared.level_offsets is not None else wp.zeros(1, dtype=wp.int32, device=device),
                prepared.bounds, prepared.top_level, prepared.leaf_size, prepared.n_work, prepared.first, prepared.steps,
                params.d0 if d_start is None else d_start, params.dx, params.R, params.E_star, params.F_N, 1.0 / params.m, params.dt, force, accel, lost],
        device=device,
    )
    return force, accel, int(lost.numpy().sum())


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


