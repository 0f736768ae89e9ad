"""Speed of the boundary-element reference (mdroll.bem): one solve of an n x n rough contact, and a
rolling ensemble of B realizations x P positions, on one device; JSON with the environment.

    python benchmarks/bem_speed.py --device cuda:0 --out bem.json            # n 256, B 64, P 2000
    python benchmarks/bem_speed.py --device cpu --n 64 --batch 2 --positions 10 --out bem-cpu.json

The problem: a wheel (R 0.5 m) on steel (E* from E 210 GPa, nu 0.3) at its Hertz approach for 40 kN
(displacement control, the decoupled mode; --control load for load control), the grid 1.25 x the
Hertz contact diameter, a self-affine isotropic surface (H 0.7, q_min 2 pi / 5 mm, RMS 0.5 um).
With --reference the single solve is also timed in ContactMechanics (if installed) on the same
problem. docs/bem.md counts the floor these times are to be read against.
"""

import argparse
import json
import math
import time

import numpy as np

from mdroll import physics
from mdroll.bem import roll, self_affine, solve
from mdroll.bem.solver import indenter_gap
from mdroll.provenance import environment

E_STAR = physics.effective_modulus(210e9, 0.3)
RADIUS = 0.5
LOAD = 40e3
#: bytes of one FFT pass over the padded grid per surface: the (2n, n + 1) complex half spectrum
COMPLEX_BYTES = 16


def problem(n, realizations, length):
    """dx (m), the approach (m) and the surfaces (B, length, n) of the benchmark."""
    d0 = physics.hertz_indentation(LOAD, E_STAR, RADIUS)
    dx = 1.25 * 2.0 * physics.contact_radius(d0, RADIUS) / n
    surfaces = self_affine((length, n), dx, H=0.7, q_min=2 * math.pi / 5e-3, rms=0.5e-6, seed=2026,
                           indices=range(realizations))
    return dx, d0, surfaces


def timed(call, warmup):
    """(seconds, result) of ``call()`` after ``warmup()``, a small run of the same shapes (FFT plans,
    CuPy's kernels). The results come back on the host, so the clock includes the device's work."""
    warmup()
    start = time.perf_counter()
    result = call()
    return time.perf_counter() - start, result


def control(args, d0):
    return {"approach": d0} if args.control == "approach" else {"load": LOAD}


def single_solve(args):
    dx, d0, surfaces = problem(args.n, 1, args.n)
    heights = surfaces[0]
    def call():
        return solve(heights, dx, RADIUS, E_star=E_STAR, device=args.device, **control(args, d0))

    seconds, result = timed(call, call)
    # two padded FFTs per convolution, two convolutions per iteration, one more to start from the overlap
    passes = 4 * int(result.iterations) + (2 if args.control == "approach" else 0)
    record = {"n": args.n, "dx": dx, "seconds": seconds, "iterations": int(result.iterations),
              "force": result.force, "area": result.area, "fft_passes": passes,
              "bytes_per_pass": COMPLEX_BYTES * 2 * args.n * (args.n + 1),
              "seconds_per_iteration": seconds / int(result.iterations)}
    if args.reference:
        record["reference"] = contactmechanics_solve(heights, dx, d0, result.force)
    return record


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


def rolling_ensemble(args):
    dx, d0, surfaces = problem(args.n, args.batch, args.n + args.positions - 1)
    def call(steps):
        return roll(surfaces, dx, RADIUS, E_star=E_STAR, steps=steps, device=args.device, **control(args, d0))

    seconds, result = timed(lambda: call(args.positions), lambda: call(2))
    iterations = result.iterations
    return {"n": args.n, "batch": args.batch, "positions": args.positions, "seconds": seconds,
            "seconds_per_position": seconds / args.positions,
            "iterations_mean": float(iterations.mean()), "iterations_max": int(iterations.max()),
            "iterations_first_position": float(iterations[:, 0].mean()),
            "converged": bool(np.all(result.converged)),
            "force_mean": float(result.force.mean()), "force_std": float(result.force.std())}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--n", type=int, default=256, help="cells across the square window")
    parser.add_argument("--batch", type=int, default=64, help="realizations rolled at once")
    parser.add_argument("--positions", type=int, default=2000, help="rolling positions, one cell apart")
    parser.add_argument("--control", choices=("approach", "load"), default="approach")
    parser.add_argument("--reference", action="store_true", help="also time ContactMechanics on the single solve")
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    record = {"environment": environment(args.device), "control": args.control, "single": single_solve(args)}
    print(json.dumps(record["single"]), flush=True)
    record["rolling"] = rolling_ensemble(args)
    print(json.dumps(record["rolling"]), flush=True)
    with open(args.out, "w") as out:
        json.dump(record, out, indent=1)


if __name__ == "__main__":
    main()
