"""The scaling study behind ``mdroll bench``: measured cost of the registered force algorithms
(:mod:`mdroll.forces.registry`: their names, bench variants, expected exponents and sizes).

Sections (each a list of timed points, each point the median of ``repeats`` runs on fresh lines,
the device synchronized before every clock read, after a warm-up whose compile time is
reported apart; a CUDA force kernel alone is timed on the device's clock, :func:`device_timed`):

- ``refinement``: fixed L, dx halving (n doubles, springs in contact double): direct ~ n^2,
  tree ~ n log n, edge ~ n (each entry's ``complexity``); the exponent of time vs n is fitted
  on log-log by least squares.
- ``distance``: fixed dx, L growing (n grows, contact fixed): all ~ n.
- ``ensemble``: throughput (realization-steps per second) against the number of realizations R.
- ``cpu_vs_cuda``: the same run on both devices and their ratio (when CUDA is present).
- ``stages``: the stage breakdown of a warm end-to-end ``run_ensemble``.
- ``memory``: bytes of device arrays per realization, counted from the arrays a batch allocates.
- ``thesis`` (``--full`` on CUDA): 300 x 2^20 force-only and warm end-to-end times per algorithm.

The study lives in the package (not under ``benchmarks/``) so the installed ``mdroll bench``
has it; ``benchmarks/`` holds the pytest-benchmark suite, scripts and the recorded results.
Its table and plot: :mod:`mdroll.bench.report`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..devices import resolve_device, synchronize, to_warp, usable_devices, warp
from ..ensemble.lines import rough_lines
from ..ensemble.pipeline import H_BOUND_SIGMAS, MODES, run_ensemble
from ..experiments import Ladder, provenance
from ..forces.force import force_command
from ..forces.prepare import prepare_lines
from ..forces.prepared import DEFAULT_BAND_LIMIT, DEFAULT_LEAF_SIZE
from ..forces.registry import ALGORITHMS, REGISTRY
from ..params import Params
from .clocks import CLOCKS, device_timed, timed


@dataclass(frozen=True)
class ScalingSize:
    """The scaling study's parameters on one rung of the ladder (:data:`SIZES`). ``refinement``: (L in m, log2 n values, realizations); ``distance``:
    (log2 n values at the default dx, realizations); ``ensemble``: (log2 n, R values);
    ``cpu_refinement`` / ``cpu_distance``: the CPU's own (smaller) sweeps, default the same."""

    repeats: int
    refinement: tuple
    distance: tuple
    ensemble: tuple
    compare: tuple  # (log2 n, realizations) of the CPU-vs-CUDA run
    stages: tuple  # (Params, realizations) of the end-to-end run whose stages are timed
    thesis: bool
    cpu_refinement: tuple | None = None
    cpu_distance: tuple | None = None
    #: CUDA realizations per section and algorithm where they differ from the section's own
    cuda_realizations: dict = field(default_factory=dict)

    def sweeps(self, device: str) -> dict:
        """``{section: ([Params per size], realizations)}`` for ``device``."""
        cpu = device == "cpu"
        length, exps, reps = (self.cpu_refinement if cpu and self.cpu_refinement else self.refinement)
        exps_d, reps_d = (self.cpu_distance if cpu and self.cpu_distance else self.distance)
        return {"refinement": ([Params(L=length, dx=length / 2**e) for e in exps], reps),
                "distance": ([Params(L=2**e * 5e-6) for e in exps_d], reps_d)}

    def realizations(self, device: str, section: str, algorithm: str) -> int:
        """Lines a size of ``section`` times ``algorithm`` with on ``device``: the section's own
        (:meth:`sweeps`), or on CUDA its entry in ``cuda_realizations``."""
        reps = self.sweeps(device)[section][1]
        return self.cuda_realizations.get(section, {}).get(algorithm, reps) if device.startswith("cuda") else reps


SIZES = Ladder(
    # minutes on a CPU
    quick=ScalingSize(repeats=3, refinement=(0.05, (12, 13, 14, 15, 16), 8), distance=((14, 15, 16, 17, 18), 4),
                       ensemble=(15, (1, 2, 4, 8, 16)), compare=(15, 4), stages=(Params(L=0.2), 8), thesis=False),
    # a GPU: CUDA sizes large enough to fill it (tens of millions of steps), the CPU (one core per
    # launch) its own smaller sweeps
    full=ScalingSize(repeats=5, refinement=(0.25, (17, 18, 19, 20, 21, 22), 64), distance=((16, 17, 18, 19, 20, 21, 22), 64),
                      ensemble=(18, (1, 4, 16, 64, 256, 1024)), compare=(18, 64), stages=(Params(L=5.24288), 300),
                      thesis=True, cpu_refinement=(0.25, (13, 14, 15, 16, 17, 18), 1),
                      cpu_distance=((14, 15, 16, 17, 18, 19, 20, 21, 22), 1),
                      # the fast forms' smallest launches at 64 lines come near the latency of a
                      # launch and of its clock, which flattens the fitted slopes; 256 lines keep
                      # every size well above them (docs/performance.md)
                      cuda_realizations={"refinement": {"edge": 256, "sweep": 256},
                                         "distance": {"edge": 256, "tree": 256, "sweep": 256}}),
)


def fit_exponent(n, t) -> tuple[float, float]:
    """Least-squares slope p of log t = p log n + c and its standard error."""
    x, y = np.log(np.asarray(n, float)), np.log(np.asarray(t, float))
    if x.size < 3:
        return float(np.polyfit(x, y, 1)[0]), math.nan
    coef, cov = np.polyfit(x, y, 1, cov=True)
    return float(coef[0]), float(math.sqrt(cov[0, 0]))


def force_time(params: Params, algorithm: str, realizations: int, device: str, repeats: int,
               boundary: str = "periodic", leaf_size: int = DEFAULT_LEAF_SIZE, band_limit: int = DEFAULT_BAND_LIMIT,
               clock: str = "device") -> dict:
    """Median time (s) of the force kernel alone and of the per-line build, on fresh lines each
    repeat; ``leaf_size`` and ``band_limit`` tune the tree (:func:`mdroll.contact_force`).

    The launch is recorded outside the clock (:func:`mdroll.forces.force.force_command`):
    its host work, the same whatever n, would otherwise flatten the slopes of the small GPU
    sizes. ``clock="device"`` times the kernel on CUDA by :func:`device_timed`, ``"wall"`` with
    the host's clock around its launch (:func:`timed`, which adds the launch's own latency)."""
    if clock not in CLOCKS:
        raise ValueError(f"clock = {clock!r}: force_time's clocks are {', '.join(map(repr, CLOCKS))}")
    wp = warp()
    d = params.d0
    h_bound = H_BOUND_SIGMAS * params.h0

    def fresh_lines(seed):
        return to_warp(rough_lines(params, seed, realizations, device=device), device)

    def build(lines):
        return prepare_lines(lines, params, algorithm, boundary, d, device, leaf_size, h_bound, band_limit)

    steps = build(fresh_lines(0)).steps
    out = wp.empty((realizations, steps), dtype=wp.float64, device=device)

    def recorded(i):
        prepared = build(fresh_lines(i + 1))
        return force_command(prepared, params, algorithm, d, device, out=out)[0], prepared

    def launch(command_and_lines):
        command_and_lines[0].launch()

    force_s, times = (timed if clock == "wall" else device_timed)(launch, device, repeats, setup=recorded)
    build_s, _ = timed(build, device, repeats, setup=lambda i: fresh_lines(i + 1))
    return {"algorithm": algorithm, "device": device, "n": params.n_points, "dx": params.dx, "L": params.length,
            "realizations": realizations, "steps": steps, "force_s": force_s, "force_times_s": times, "build_s": build_s,
            "leaf_size": leaf_size, "band_limit": band_limit, "ns_per_step": force_s / (realizations * steps) * 1e9,
            "clock": "device events" if clock == "device" and device.startswith("cuda") else "wall",
            "springs_in_contact": params.springs_in_contact}


def _allowed(device: str, algorithm: str, n: int, realizations: int, full: bool) -> bool:
    limit = point_limit(device, algorithm)
    return not full or limit is None or n * realizations <= limit


def point_limit(device: str, algorithm: str) -> int | None:
    """The largest problem (realizations x points) of a full study on ``device`` (the registry
    entry's ``bench_point_limit``; None: no limit)."""
    return REGISTRY[algorithm].bench_point_limit.get("cpu" if device == "cpu" else "cuda")


def compile_time(device: str) -> float:
    """Seconds of the first use of every kernel (compilation or cache load, module load) on a tiny problem."""
    small = Params(L=0.03)
    t0 = time.perf_counter()
    for algorithm in ALGORITHMS:
        for mode in MODES if REGISTRY[algorithm].coupled is not None else ("decoupled",):
            run_ensemble(small, realizations=2, algorithm=algorithm, mode=mode, device=device, progress=False)
    synchronize(device)
    return time.perf_counter() - t0


def memory_per_realization(params: Params, algorithm: str, device: str) -> int:
    """Bytes of the device arrays one realization occupies in a batch (lines, prefix sums, tree,
    bounds, force, acceleration, two half spectra), counted from the arrays themselves, after its
    force launch is recorded (a form may build its prefix sums there: the sweep's on the CPU)."""
    lines = to_warp(rough_lines(params, 0, 1, device=device), device)
    prepared = prepare_lines(lines, params, algorithm, "open", params.d0, device, h_max=H_BOUND_SIGMAS * params.h0)
    force_command(prepared, params, algorithm, params.d0, device)
    arrays = [prepared.lines, prepared.bounds, prepared.prefix, prepared.tree]
    total = sum(a.capacity for a in arrays if a is not None) + (0 if prepared.lines is lines else lines.capacity)
    force_bytes = 8 * prepared.steps
    spectrum_bytes = 16 * (prepared.steps // 2 + 1)
    return int(total + 2 * force_bytes + 2 * spectrum_bytes)


def run_study(size: str = "quick", devices=None, progress=print) -> dict:
    """Run the study of ``size`` ("quick" or "full") on ``devices`` (default: every available
    one; CUDA only with CuPy) and return the JSON-ready record: the provenance of
    :func:`mdroll.experiments.provenance` (one environment per device) and the sections."""
    study = SIZES.rung(size)
    full = size == "full"
    devices = [resolve_device(d) for d in (devices or usable_devices()[:2])]
    record = {**provenance(devices[0], size, None, study, devices=devices), "compile_s": {}, "refinement": [],
              "distance": [], "ensemble": [], "cpu_vs_cuda": [], "stages": {}, "memory_bytes_per_realization": {},
              "fits": {}, "thesis": {}}
    for device in devices:
        record["compile_s"][device] = compile_time(device)
        progress(f"{device}: first use (compile/load) {record['compile_s'][device]:.2f} s")

    for section in ("refinement", "distance"):
        for device in devices:
            sizes, reps = study.sweeps(device)[section]
            for algorithm in ALGORITHMS:
                count = study.realizations(device, section, algorithm)
                for p in sizes:
                    if _allowed(device, algorithm, p.n_points, count, full):
                        record[section].append(force_time(p, algorithm, count, device, study.repeats))
                _fit(record, section, device, algorithm, progress)
            if section == "refinement":
                for entry in REGISTRY.values():
                    for variant in entry.bench_variants:
                        for p in sizes:
                            if _allowed(device, entry.name, p.n_points, reps, full):
                                point = force_time(p, entry.name, reps, device, study.repeats, **variant.options)
                                record[section].append({**point, "algorithm": variant.name})
                        _fit(record, section, device, variant.name, progress)
    e, counts = study.ensemble
    for device in devices:
        for algorithm in ALGORITHMS:
            for count in counts:
                if _allowed(device, algorithm, 2**e, count, full):
                    point = force_time(Params(L=2**e * 5e-6), algorithm, count, device, study.repeats)
                    point["realization_steps_per_s"] = count * point["steps"] / point["force_s"]
                    record["ensemble"].append(point)
    if len(devices) > 1:
        e, count = study.compare
        p = Params(L=2**e * 5e-6)
        for algorithm in ALGORITHMS:
            # the same run on every device, on one clock (the wall's, launch included); direct with
            # fewer realizations so one CPU core finishes
            runs = min(count, max(1, (point_limit("cpu", algorithm) or count * p.n_points) // p.n_points))
            times = {d: force_time(p, algorithm, runs, d, study.repeats, clock="wall")["force_s"] for d in devices}
            cpu = times.get("cpu")
            record["cpu_vs_cuda"].append({"algorithm": algorithm, "n": p.n_points, "realizations": runs, "times_s": times,
                                          **{f"speedup_{d}": cpu / t for d, t in times.items() if d != "cpu" and cpu}})
    for device in devices:
        stages_params, count = study.stages if device.startswith("cuda") or not full else (Params(L=0.2), 8)
        run_ensemble(stages_params, realizations=count, device=device, progress=False)  # warm-up: plans, pools
        result = run_ensemble(stages_params, realizations=count, device=device, progress=False)
        record["stages"][device] = {"params": {"L": stages_params.L, "n_real": count},
                                    "timings_s": result.timings, "total_s": sum(result.timings.values())}
        record["memory_bytes_per_realization"][device] = {
            alg: memory_per_realization(Params(), alg, device) for alg in ALGORITHMS}
        progress(f"{device}: warm end to end {record['stages'][device]['total_s']:.3f} s")
    if study.thesis:
        for device in (d for d in devices if d.startswith("cuda")):
            record["thesis"][device] = thesis_scale(device, study.repeats, progress)
    return record


def thesis_scale(device: str, repeats: int, progress=print) -> dict:
    """300 x 2^20, open boundary: force-only, warm end-to-end (decoupled) and coupled end-to-end
    (one run, kernels already compiled) per algorithm."""
    p, count = Params(L=5.24288), 300
    out = {"force": {}, "end_to_end": {}, "coupled": {}}
    for algorithm in ALGORITHMS:
        out["force"][algorithm] = force_time(p, algorithm, count, device, repeats, boundary="open")
        progress(f"{device} thesis force {algorithm}: {out['force'][algorithm]['force_s'] * 1e3:.2f} ms")
    for algorithm in ALGORITHMS:
        run_ensemble(p, realizations=count, algorithm=algorithm, device=device, progress=False)
        total, times = timed(lambda: run_ensemble(p, realizations=count, algorithm=algorithm, device=device,
                                                  progress=False), device, 3)
        out["end_to_end"][algorithm] = {"total_s": total, "times_s": times}
        progress(f"{device} thesis end to end {algorithm}: {total:.3f} s")
    for algorithm in (name for name in ALGORITHMS if REGISTRY[name].coupled is not None):
        t0 = time.perf_counter()  # run_ensemble returns after its result is on the host
        timings = run_ensemble(p, realizations=count, algorithm=algorithm, mode="coupled", device=device,
                               progress=False).timings
        out["coupled"][algorithm] = {"total_s": time.perf_counter() - t0, "timings_s": timings}
        progress(f"{device} thesis coupled {algorithm}: {out['coupled'][algorithm]['total_s']:.3f} s "
                 f"(dynamics {timings['response']:.3f} s)")
    return out


def _fit(record, section, device, algorithm, progress):
    points = [r for r in record[section] if r["device"] == device and r["algorithm"] == algorithm]
    if len(points) < 2:
        return
    slope, err = fit_exponent([r["n"] for r in points], [r["force_s"] for r in points])
    record["fits"].setdefault(section, {}).setdefault(device, {})[algorithm] = {"exponent": slope, "stderr": err}
    progress(f"{device} {section:<10} {algorithm:<6} time ~ n^{slope:.3f} +- {err:.3f} "
             f"({len(points)} sizes, {points[0]['n']}..{points[-1]['n']})")
