"""The summary pass over 300 force series of 1,036,800 steps (2.5 GB, read once) with different
numbers of threads per row: 1024 a row is 307,200 threads, ~1.1 waves of the H200's 270,336
resident threads, so a second, nearly empty wave may cost as much as the first.

    python benchmarks/probes/summary_probe.py --out summary.json
"""
import argparse
import json
import numpy as np

from mdroll import Params
from mdroll.bench import timed
from mdroll.devices import to_warp, warp
from mdroll.ensemble import spectra
from mdroll.kernels import spectra as kernels

wp = warp()
DEVICE = "cuda:0"
P = Params(L=5.24288)


def median_ms(fn):
    fn()  # warm-up
    return 1e3 * timed(fn, DEVICE, 7)[0]


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", default="summary.json")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    deviation = to_warp(rng.standard_normal((300, 1_036_800)), DEVICE)
    record = {"sm_count": wp.get_device(DEVICE).sm_count, "series_sums_ms": {}}
    reference = None
    for threads in (128, 256, 448, 512, 768, 896, 1024, 2048):
        kernels.SUMMARY_THREADS = threads
        record["series_sums_ms"][threads] = median_ms(lambda: spectra.series_sums(deviation, P, DEVICE, True))
        sums = spectra.series_sums(deviation, P, DEVICE, True)
        reference = sums if reference is None else reference
        print(threads, round(record["series_sums_ms"][threads], 3), "max rel diff",
              float(np.max(np.abs(sums - reference) / np.maximum(np.abs(reference), 1e-300))), flush=True)
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
