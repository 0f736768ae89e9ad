"""Where a fused CUDA iteration of mdroll.bem spends its time: each kernel of an iteration alone, captured
20 times in a CUDA graph and timed by events, for a lone surface and a batch, beside the padded 2-D cuFFT
convolution it replaced; and a lone solve's time outside the iterations (host clock). JSON with the
environment and the commit; docs/bem.md reads it.

    python benchmarks/bem_profile.py --device cuda:0 --out bem-profile.json     # n 256, batch 64
"""

import argparse
import json

import numpy as np

from bem_speed import E_STAR, RADIUS, commit, graph_seconds, median_seconds, primed_solver, problem
from mdroll.bem import solve
from mdroll.bem.solver import device_gap, initial_pressure, workspace
from mdroll.provenance import environment

def graph_microseconds(stream, body):
    """Microseconds of one ``body()`` (:func:`bem_speed.graph_seconds`)."""
    return graph_seconds(stream, body) * 1e6


def kernels(n, batch):
    """Each stage of an iteration (every member active, contact everywhere), microseconds."""
    import cupy
    from cupy.cuda import cufft
    from cupyx.scipy.fft import get_fft_plan

    from mdroll.bem import fused

    s = primed_solver(n, batch)
    out = {}
    with s.stream:
        grid, block, cells, load, k = (s.chunks, batch), (fused.THREADS,), np.int32(n), np.int32(0), s.kernels
        stages = {
            "rows_forward": lambda: s.forward.fft(s.p, s.spectra, cufft.CUFFT_FORWARD),
            "columns": lambda: k["columns"]((-(-(n + 1) // fused.COLUMNS), batch), (fused.COLUMN_THREADS,),
                                            (s.spectra, s.kernel, s.twiddle, s.state, cells, np.int32(s.bits)),
                                            shared_mem=s.shared),
            "rows_inverse": lambda: s.inverse.fft(s.spectra, s.u, cufft.CUFFT_INVERSE),
            "convolution": lambda: s.convolve(s.p, s.u),
            "gap_norm": lambda: k["gap_norm"](grid, block, (s.u, s.p, s.separation, s.state, s.partials,
                                                            s.arrivals, cells, load)),
            "direction": lambda: k["direction"](grid, block, (s.u, s.p, s.separation, s.t, s.state, cells)),
            "step_sums": lambda: k["step_sums"](grid, block, (s.u, s.r, s.p, s.separation, s.t, s.state,
                                                              s.partials, s.arrivals, cells, load)),
            "update": lambda: k["update"](grid, block, (s.u, s.r, s.separation, s.t, s.state, s.partials,
                                                        s.arrivals, cells, np.int32(1))),
            "iteration": s._iteration}
        out = {name: graph_microseconds(s.stream, body) for name, body in stages.items()}
        padded = cupy.zeros((batch, 2 * n, 2 * n))
        spectra = cupy.empty((batch, 2 * n, n + 1), dtype=cupy.complex128)
        forward = get_fft_plan(padded, axes=(-2, -1), value_type="R2C")
        inverse = get_fft_plan(spectra, shape=(2 * n, 2 * n), axes=(-2, -1), value_type="C2R")
        weights = cupy.ones((2 * n, n + 1))
        product = cupy.ElementwiseKernel("float64 w", "complex128 c", "c = c * w", "bem_profile_product")
        out["padded_2d_forward"] = graph_microseconds(s.stream, lambda: forward.fft(padded, spectra,
                                                                                     cufft.CUFFT_FORWARD))
        out["padded_2d_product"] = graph_microseconds(s.stream, lambda: product(weights, spectra))
        out["padded_2d_inverse"] = graph_microseconds(s.stream, lambda: inverse.fft(spectra, padded,
                                                                                     cufft.CUFFT_INVERSE))
    return out


def lone_solve(n, device):
    """A lone solve of the benchmark's problem and its parts outside the iterations, milliseconds."""
    import cupy

    dx, d0, surfaces = problem(n, 1, n)
    heights = surfaces[0]

    def median_ms(call, repeats=7):
        def synced():  # the calls leave their results on the device: wait for its work
            call()
            cupy.cuda.Device().synchronize()
        return median_seconds(synced, repeats)[0] * 1e3

    control = np.array([d0])
    result = solve(heights, dx, RADIUS, E_star=E_STAR, approach=d0, device=device)
    op, solver = workspace(device, n, dx, E_STAR, 1, False)

    def separation():
        return device_gap(device, n, dx, RADIUS, RADIUS) - cupy.asarray(heights).reshape(1, n, n)

    gap = separation()
    start = initial_pressure(op, gap, control, False, RADIUS)
    return {"iterations": int(result.iterations),
            "solve_ms": median_ms(lambda: solve(heights, dx, RADIUS, E_star=E_STAR, approach=d0, device=device)),
            "solver_call_ms": median_ms(lambda: solver(gap, control, start, 1e-10, 2000)),
            "initial_pressure_ms": median_ms(lambda: initial_pressure(op, gap, control, False, RADIUS)),
            "separation_ms": median_ms(separation)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--n", type=int, default=256, help="cells across the square window")
    parser.add_argument("--batch", type=int, default=64, help="members of the batched profile")
    parser.add_argument("--commit", default=None, help="commit of the code measured (default: git rev-parse HEAD)")
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    import cupy

    with cupy.cuda.Device(int(args.device.partition(":")[2] or 0)):
        record = {"environment": {**environment(args.device), "commit": args.commit or commit()}, "n": args.n,
                  "microseconds_lone": kernels(args.n, 1),
                  f"microseconds_batch_{args.batch}": kernels(args.n, args.batch),
                  "lone_solve": lone_solve(args.n, args.device)}
    print(json.dumps(record, indent=1), flush=True)
    with open(args.out, "w") as out:
        json.dump(record, out, indent=1)


if __name__ == "__main__":
    main()
