"""Where the time of one warm end-to-end batch goes (300 x 2^20, decoupled, CUDA): each pipeline
sub-step timed alone, the device synchronized around it, median of 3.

    python benchmarks/profile_stages.py --algorithm edge --out profile.json

It calls the same functions as ``run_ensemble`` in the same order; docs/performance.md records
the numbers and what they point at.
"""

import argparse
import json
import statistics
import time

from mdroll import Params
from mdroll.devices import resolve_device, synchronize, to_warp
from mdroll.fft import rfft_rows
from mdroll.forces.force import launch_force
from mdroll.forces.prepare import prepare_lines
from mdroll.ensemble.lines import random_spectra, rough_lines
from mdroll.ensemble.checkpoint import RunTotals
from mdroll.ensemble.pipeline import H_BOUND_SIGMAS
from mdroll.ensemble.psd import psd_moments_of_batch, series_sums, to_host
from mdroll.provenance import environment


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--algorithm", default="edge")
    parser.add_argument("--out", default="profile.json")
    args = parser.parse_args()
    device = resolve_device(args.device)
    import numpy as np

    p = Params(L=5.24288)
    idx = np.arange(300)
    times = {}

    def clock(name, fn):
        runs = []
        for _ in range(3):
            synchronize(device)
            t0 = time.perf_counter()
            out = fn()
            synchronize(device)
            runs.append(time.perf_counter() - t0)
        times[name] = statistics.median(runs)
        return out

    for _ in range(2):  # the second pass is the warm one that is kept
        clock("random spectra (part of generate)", lambda: random_spectra(p, 0, idx, device))
        lines = clock("generate", lambda: to_warp(rough_lines(p, 0, idx, device=device), device))
        prepared = clock("build", lambda: prepare_lines(lines, p, args.algorithm, "open", p.d0, device,
                                                        h_max=H_BOUND_SIGMAS * p.h0))
        force = clock("force", lambda: launch_force(prepared, p, args.algorithm, p.d0, device, offset=p.F_N))
        sums = clock("response (force sums, final state)", lambda: series_sums(force, p, device, True))
        clock("rfft", lambda: rfft_rows(force, device))
        moments = clock("spectra (rfft, PSD moments)", lambda: psd_moments_of_batch(force, None, sums, p, device))

        def merge():
            totals = RunTotals(steps=prepared.steps)
            totals.add_moments(len(idx), moments[0], moments[1])
            totals.add_sums(to_host(sums), p.F_N)

        clock("merge into the running moments", merge)
    record = {"environment": environment(device), "algorithm": args.algorithm, "times_s": times}
    for name, t in times.items():
        print(f"{name:<30} {t * 1e3:8.2f} ms")
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
