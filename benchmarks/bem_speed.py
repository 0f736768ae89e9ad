"""Speed of the boundary-element reference (mdroll.bem) against its floor: one solve of an n x n rough
contact (NumPy, and on CUDA the fused solver alone and batched, and the unfused CuPy iteration), the
floor measured on the device for the batch and for a lone surface (a padded convolution, an iteration,
a kernel launch in a graph, a device-to-device copy), and a rolling ensemble of B realizations x P
positions; JSON with the environment and the commit.

    python benchmarks/bem_speed.py --device cuda:0 --cpu-reference --out bem.json     # n 256, B 64, P 2000
    python benchmarks/bem_speed.py --device cpu --n 64 --batch 2 --positions 10 --out bem-cpu.json

The problem: a wheel (R 0.5 m) on steel (E* from E 210 GPa, nu 0.3) at its Hertz approach for 40 kN
(displacement control, the decoupled mode; --control load for load control), the grid 1.25 x the
Hertz contact diameter, a self-affine isotropic surface (H 0.7, q_min 2 pi / 5 mm, RMS 0.5 um).
With --reference the single solve is also timed in ContactMechanics (if installed) on the same problem.
The single solves use the default tolerance, the rolling run --tol. docs/bem.md reads these numbers
against the floor.
"""

import argparse
import json
import math
import statistics
import subprocess
import time
from types import SimpleNamespace

import numpy as np

from mdroll import physics
from mdroll.bem import roll, self_affine, solve
from mdroll.bem.halfspace import HalfSpace
from mdroll.bem.solver import TOLERANCE, constrained_cg, indenter_gap, initial_pressure
from mdroll.provenance import environment

E_STAR = physics.effective_modulus(210e9, 0.3)
RADIUS = 0.5
LOAD = 40e3
REPEATS = 5


def problem(n, realizations, length):
    """dx (m), the approach (m) and the surfaces (B, length, n) of the benchmark."""
    d0 = physics.hertz_indentation(LOAD, E_STAR, RADIUS)
    dx = 1.25 * 2.0 * physics.contact_radius(d0, RADIUS) / n
    surfaces = self_affine((length, n), dx, H=0.7, q_min=2 * math.pi / 5e-3, rms=0.5e-6, seed=2026,
                           indices=range(realizations))
    return dx, d0, surfaces


def median_seconds(call, repeats):
    """(median seconds, last result) of ``call()`` after one untimed call (FFT plans, kernels). Every
    call returns results on the host, so the clock includes the device's work."""
    result = call()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = call()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def control(args, d0):
    return {"approach": d0} if args.control == "approach" else {"load": LOAD}


def record_of(seconds, result, batch=1):
    iterations = np.asarray(result.iterations)
    return {"seconds": seconds, "seconds_per_solve": seconds / batch, "iterations": iterations.tolist(),
            "seconds_per_iteration_and_surface": seconds / float(iterations.max()) / batch,
            "force": np.asarray(result.force).tolist()}


def single_solves(args):
    """One n^2 solve: NumPy (device cpu or --cpu-reference), fused CUDA alone and in a batch of B
    different surfaces, and the unfused CuPy iteration on the same surface."""
    dx, d0, surfaces = problem(args.n, args.batch, args.n)
    kw = dict(E_star=E_STAR, **control(args, d0))
    out = {"n": args.n, "dx": dx}
    if args.device == "cpu" or args.cpu_reference:
        out["numpy"] = record_of(*median_seconds(lambda: solve(surfaces[0], dx, RADIUS, **kw), 1))
    if args.reference:
        out["reference"] = contactmechanics_solve(surfaces[0], dx, d0, solve(surfaces[0], dx, RADIUS, **kw).force)
    if args.device == "cpu":
        return out
    import cupy

    out["fused"] = record_of(*median_seconds(lambda: solve(surfaces[0], dx, RADIUS, device=args.device, **kw),
                                             REPEATS))
    out["fused_batch"] = record_of(*median_seconds(
        lambda: solve(surfaces, dx, RADIUS, device=args.device, **kw), REPEATS), args.batch)
    with cupy.cuda.Device(int(args.device.partition(":")[2] or 0)):
        op = HalfSpace(args.n, dx, E_STAR, xp=cupy)
        separation = cupy.asarray(indenter_gap(args.n, dx, RADIUS, RADIUS) - surfaces[:1])
        target = np.array([d0 if args.control == "approach" else LOAD])
        load = args.control == "load"

        def unfused():
            start = initial_pressure(op, separation, target, load, RADIUS)
            p, _, iterations, _ = constrained_cg(op, separation, target, load, start, TOLERANCE, 2000)
            return SimpleNamespace(force=float(p.sum()) * dx * dx, iterations=int(iterations[0]))

        out["unfused"] = record_of(*median_seconds(unfused, 1))
    return out


def contactmechanics_solve(heights, dx, d0, force):
    """ContactMechanics' time on the same problem under displacement control, or why not."""
    try:
        from ContactMechanics import FreeFFTElasticHalfSpace
        from ContactMechanics.Optimization import constrained_conjugate_gradients
    except ImportError:
        return {"skipped": "ContactMechanics not installed (pip install -e '.[bem]')"}
    n = heights.shape[0]
    substrate = FreeFFTElasticHalfSpace((n, n), E_STAR, (n * dx, n * dx))
    topography = heights - indenter_gap(n, dx, RADIUS, RADIUS)
    start = time.perf_counter()
    result = constrained_conjugate_gradients(substrate, topography, offset=d0, pentol=1e-14, forcetol=1e-30,
                                             thermotol=1e-10, maxiter=10000)
    seconds = time.perf_counter() - start
    theirs = float(result.jac[:n, :n].sum())
    return {"seconds": seconds, "iterations": int(result.nit), "force": theirs, "force_ratio": force / theirs}


def primed_solver(n, batch):
    """A fused solver of ``batch`` members on n x n cells for timing its stages: pressure and
    separation random (seeded), every member active, with contact everywhere."""
    import cupy

    from mdroll.bem import fused

    solver = fused.FusedCG(HalfSpace(n, 1e-5, E_STAR, xp=cupy), batch, False)
    with solver.stream:
        solver.p[:, :, :n] = cupy.random.default_rng(1).random((batch, n, n))
        solver.separation[...] = cupy.random.default_rng(2).random((batch, n, n))
        state = np.zeros((batch, fused.FIELDS))
        state[:, fused.ACTIVE], state[:, fused.MAX_ITER], state[:, fused.G_OLD] = 1.0, 1e18, 1.0
        solver.state.set(state)
    return solver


def graph_seconds(stream, body, repeats=20):
    """Seconds of one ``body()``: captured ``repeats`` times in a CUDA graph, the graph's replay
    timed by events after one untimed replay."""
    import cupy

    stream.begin_capture()
    for _ in range(repeats):
        body()
    graph = stream.end_capture()
    start, end = cupy.cuda.Event(), cupy.cuda.Event()
    graph.launch(stream)
    start.record(stream)
    graph.launch(stream)
    end.record(stream)
    end.synchronize()
    return cupy.cuda.get_elapsed_time(start, end) / 1e3 / repeats


def floor(args):
    """The floor measured on the device, for the batch and for a lone surface: a padded convolution
    (2 per iteration), an iteration of the fused solver that never converges (tol 0), a kernel
    launch in a graph (an element-wise kernel of a member that is skipped), and the copy bandwidth
    for the element-wise passes (read + write bytes over time)."""
    import cupy

    from mdroll.bem import fused

    n = args.n
    out = {}
    for batch in (args.batch, 1):
        solver = primed_solver(n, batch)
        with solver.stream:
            convolution = graph_seconds(solver.stream, lambda: solver.convolve(solver.p, solver.u))
            iteration = graph_seconds(solver.stream, solver._iteration)
            solver.state[:, fused.ACTIVE] = 0.0
            launch = graph_seconds(solver.stream, lambda: solver.kernels["direction"](
                (solver.chunks, batch), (256,), (solver.u, solver.p, solver.separation, solver.t, solver.state,
                                                 np.int32(n))), 100)
        out[f"batch_{batch}"] = {"convolution_seconds_per_surface": convolution / batch,
                                 "iteration_seconds_per_surface": iteration / batch, "kernel_launch_seconds": launch}
    source = cupy.random.default_rng(2).random(2**25)
    target = cupy.empty_like(source)
    start, end = cupy.cuda.Event(), cupy.cuda.Event()
    cupy.copyto(target, source)
    start.record()
    for _ in range(10):
        cupy.copyto(target, source)
    end.record()
    end.synchronize()
    bandwidth = 2 * source.nbytes * 10 / (cupy.cuda.get_elapsed_time(start, end) / 1e3)
    # bytes per surface and iteration, n x n float64 cells read or written: element-wise kernels
    # gap_norm 3, direction 5, step_sums 5, update 5; each convolution: the row FFT reads n x 2n
    # doubles and writes n (n + 1) complex, the column kernel reads and writes them, the inverse row
    # FFT reads them and writes n x 2n doubles (cuFFT in one pass each). Kernels per iteration: three
    # per convolution and the four element-wise ones
    elementwise = 18 * 8 * n * n
    convolution_bytes = 2 * (8 * 2 * n * n + 16 * n * (n + 1)) + 2 * 16 * n * (n + 1)
    kernels = 2 * 3 + 4
    bytes_floor = (elementwise + 2 * convolution_bytes) / bandwidth
    lone = out["batch_1"]
    out.update({"batch": args.batch, "copy_bandwidth_bytes_per_second": bandwidth,
                "elementwise_bytes_per_iteration": elementwise, "convolution_bytes": convolution_bytes,
                "kernels_per_iteration": kernels,
                "floor_seconds_per_iteration_and_surface": (2 * out[f"batch_{args.batch}"][
                    "convolution_seconds_per_surface"] + elementwise / bandwidth),
                "bytes_floor_seconds_per_iteration": bytes_floor,
                "lone_floor_seconds_per_iteration": max(bytes_floor, kernels * lone["kernel_launch_seconds"])})
    return out


def rolling_ensemble(args):
    """The rolling run; its time per iteration and surface counted over the slowest member at each
    position (what a lockstep batch pays) and over every member's own iterations."""
    dx, d0, surfaces = problem(args.n, args.batch, args.n + args.positions - 1)

    def call(steps):
        return roll(surfaces, dx, RADIUS, E_star=E_STAR, steps=steps, device=args.device, tol=args.tol,
                    **control(args, d0))

    call(2)
    start = time.perf_counter()
    result = call(args.positions)
    seconds = time.perf_counter() - start
    iterations = result.iterations
    return {"n": args.n, "batch": args.batch, "positions": args.positions, "tol": args.tol, "seconds": seconds,
            "seconds_per_position": seconds / args.positions,
            "seconds_per_iteration_and_surface": seconds / float(iterations.max(axis=0).sum()) / args.batch,
            "seconds_per_member_iteration": seconds / float(iterations.sum()),
            "iterations_mean": float(iterations.mean()), "iterations_max": int(iterations.max()),
            "iterations_slowest_member_mean": float(iterations.max(axis=0).mean()),
            "iterations_first_position": float(iterations[:, 0].mean()),
            "converged": bool(np.all(result.converged)),
            "force_mean": float(result.force.mean()), "force_std": float(result.force.std())}


def commit():
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--n", type=int, default=256, help="cells across the square window")
    parser.add_argument("--batch", type=int, default=64, help="realizations solved or rolled at once")
    parser.add_argument("--positions", type=int, default=2000, help="rolling positions, one cell apart (0: none)")
    parser.add_argument("--tol", type=float, default=1e-8, help="tolerance of the rolling run")
    parser.add_argument("--control", choices=("approach", "load"), default="approach")
    parser.add_argument("--cpu-reference", action="store_true", help="also time the NumPy solve on this host")
    parser.add_argument("--reference", action="store_true", help="also time ContactMechanics on the single solve")
    parser.add_argument("--commit", default=None, help="commit of the code measured (default: git rev-parse HEAD)")
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    record = {"environment": {**environment(args.device), "commit": args.commit or commit()},
              "control": args.control, "single": single_solves(args)}
    print(json.dumps(record["single"]), flush=True)
    if args.device != "cpu":
        record["floor"] = floor(args)
        print(json.dumps(record["floor"]), flush=True)
    if args.positions:
        record["rolling"] = rolling_ensemble(args)
        print(json.dumps(record["rolling"]), flush=True)
    with open(args.out, "w") as out:
        json.dump(record, out, indent=1)


if __name__ == "__main__":
    main()
