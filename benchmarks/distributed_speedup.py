"""Speed-up of the Dask runner (mdroll.distributed) over one GPU, and identity of the spectra:
a thesis-scale ensemble (2^20 points, default algorithm, decoupled, open) of many realizations
run in this process on one GPU, then on local clusters of 1 and of every GPU (one worker per
GPU, pinned), each worker warmed up first (kernels loaded, cuFFT planned) so that the clock sees
the run and not the start-up.

    python benchmarks/distributed_speedup.py --realizations 3000 --algorithm tree --out speedup.json

On a CPU-only machine ``--device cpu`` compares 1 and N CPU worker processes instead (N from
``--workers``). The JSON records the environment, the wall times, the speed-ups and the largest
relative difference of each PSD from the in-process run.
"""

import argparse
import json
import time

import numpy as np

from mdroll import EnsembleSpec, Params, run_specs
from mdroll.distributed import DaskRunner, gpu_count, connect
from mdroll.provenance import environment


def warm_up(spec: EnsembleSpec, device: str) -> None:
    """Run a small copy of the spec on this worker: kernels compiled or loaded, FFT plans made."""
    import dataclasses

    dataclasses.replace(spec, first=0, realizations=min(spec.realizations, 8)).run(device=device)


def largest_difference(result, reference) -> float:
    names = ("force_psd", "accel_psd", "force_psd_stderr", "accel_psd_stderr")
    return max(float(np.max(np.abs(getattr(result, n) - getattr(reference, n))) / np.max(np.abs(getattr(reference, n))))
               for n in names)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--realizations", type=int, default=3000)
    parser.add_argument("--algorithm", default="tree")
    parser.add_argument("--L", type=float, default=5.24288, help="rolling distance (m); 5.24288 m = 2^20 points")
    parser.add_argument("--device", default="cuda", help="cuda (one worker per GPU) or cpu")
    parser.add_argument("--workers", type=int, default=None, help="largest cluster (default: every GPU)")
    parser.add_argument("--out", default="speedup.json")
    args = parser.parse_args()
    spec = EnsembleSpec(Params(L=args.L), seed=0, realizations=args.realizations, algorithm=args.algorithm)
    local = "cuda:0" if args.device.startswith("cuda") else "cpu"
    worker_device = "auto" if args.device.startswith("cuda") else "cpu"
    largest = args.workers or (gpu_count() if args.device.startswith("cuda") else 2)
    record = {"environment": environment(local), "spec": spec.as_dict(), "runs": {}}

    warm_up(spec, local)
    t0 = time.perf_counter()
    (reference,) = run_specs([spec], device=local)
    record["runs"]["in-process"] = {"wall_s": time.perf_counter() - t0}
    print(f"in-process: {record['runs']['in-process']['wall_s']:.3f} s")
    for workers in sorted({1, largest}):
        with connect(workers=workers, device=args.device) as client:
            client.run(warm_up, spec, worker_device)
            runner = DaskRunner(client)
            t0 = time.perf_counter()
            (result,) = runner.run_specs([spec], device=worker_device)
            wall = time.perf_counter() - t0
        record["runs"][f"{workers}-workers"] = {"wall_s": wall, "max_rel_difference": largest_difference(result, reference)}
        print(f"{workers} worker(s): {wall:.3f} s, max relative difference {largest_difference(result, reference):.2e}")
    one, many = record["runs"]["1-workers"]["wall_s"], record["runs"][f"{largest}-workers"]["wall_s"]
    record["speedup_vs_one_worker"] = one / many
    record["speedup_vs_in_process"] = record["runs"]["in-process"]["wall_s"] / many
    print(f"speed-up {largest} vs 1 worker: {one / many:.2f}x; vs in-process: {record['speedup_vs_in_process']:.2f}x")
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
