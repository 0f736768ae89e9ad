"""Where the time of one warm end-to-end batch goes (300 x 2^20, decoupled, CUDA): each pipeline
sub-step timed alone, the device synchronized around it, median of 3.

    python benchmarks/profile_stages.py --algorithm edge --out profile.json

It calls the same functions as ``run_ensemble`` in the same order; benchmarks/NOTES.md records
the numbers and what they point at.
"""

import argparse
import json
import statistics
import time

from mdroll import Params
from mdroll.devices import cupy_stream, cupy_view, resolve_device, synchronize, to_warp
from mdroll.ensemble.force import launch_force, prepare_lines
from mdroll.ensemble.lines import rough_lines
from mdroll.ensemble.pipeline import H_BOUND_SIGMAS, _check_finite, _decoupled, _Totals
from mdroll.ensemble.spectra import psd_rows, rfft_rows
from mdroll.provenance import environment


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--algorithm", default="edge")
    parser.add_argument("--out", default="profile.json")
    args = parser.parse_args()
    device = resolve_device(args.device)
    import cupy
    import numpy as np

    p = Params(L=5.24288, n_real=300)
    idx = np.arange(p.n_real)
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
        lines = clock("generate", lambda: to_warp(rough_lines(p, 0, idx, device=device), device))
        prepared = clock("build", lambda: prepare_lines(lines, p, args.algorithm, "open", p.d0, device,
                                                        h_max=H_BOUND_SIGMAS * p.h0))
        force = clock("force", lambda: launch_force(prepared, p, args.algorithm, p.d0, device))
        clock("response", lambda: _decoupled(force, p, device))
        rows = cupy_view(force)
        clock("check force finite", lambda: _check_finite(rows, "force", "force", idx))
        with cupy_stream(device):
            centred = clock("remove mean", lambda: rows - rows.mean(axis=1, keepdims=True))
            clock("rfft", lambda: rfft_rows(centred, device))
        psd = clock("psd (mean, rfft, |B|^2)", lambda: psd_rows(force, p.dx, device))
        clock("check psd finite", lambda: _check_finite(psd, "psd", "spectra", idx))
        clock("moments + force sums", lambda: _Totals().add(psd, psd, rows))
        clock("allocate 300 x 2^20 (Warp)", lambda: to_warp(cupy.empty_like(rows), device))
    record = {"environment": environment(device), "algorithm": args.algorithm, "times_s": times}
    for name, t in times.items():
        print(f"{name:<30} {t * 1e3:8.2f} ms")
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
