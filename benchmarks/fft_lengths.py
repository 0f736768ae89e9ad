"""Why open runs take a 5-smooth number of steps: cuFFT's real FFT of 300 rows at the open
boundary's natural length (1,046,492 = 4 x 397 x 659 at thesis scale) against the largest 7-smooth
and 5-smooth lengths below it (``mdroll.fft.fast_length``) and 2^20, with a
device-to-device copy of the same bytes for the memory ceiling. CUDA with CuPy only.

    python benchmarks/fft_lengths.py --out fft_lengths.json

Medians of 20 timed calls (device time, CuPy's profiler) after 3 warm-up calls, in ms. Recorded on
an H200 (docs/performance.md): 17.5 ms at 1,046,492 points, 5.3 ms at 1,036,800 = 2^10 3^4 5^2.
"""

import argparse
import json

import cupy as cp
import numpy as np
from cupyx.profiler import benchmark

from mdroll.fft import fast_length

ROWS = 300
NATURAL = 1_046_492  # open steps of 300 x 2^20 at the defaults before runs were shortened


def largest_smooth(limit: int, primes: tuple[int, ...]) -> int:
    """The largest product of powers of ``primes`` that is at most ``limit``."""
    reachable = {1}
    for p in primes:
        grown = set(reachable)
        for value in reachable:
            while value * p <= limit:
                value *= p
                grown.add(value)
        reachable = grown
    return max(reachable)


def median_ms(function, *args) -> float:
    return float(np.median(benchmark(function, args, n_repeat=20, n_warmup=3).gpu_times)) * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=None, help="write the medians (ms) as JSON here")
    args = parser.parse_args()
    x = cp.random.standard_normal((ROWS, 2**20))
    y = cp.empty_like(x)
    record = {"copy 2^20 (d2d)": median_ms(lambda a: y.__setitem__(Ellipsis, a), x)}
    lengths = {"natural": NATURAL, "7-smooth": largest_smooth(NATURAL, (2, 3, 5, 7)),
               "5-smooth": fast_length(NATURAL), "2^20": 2**20}
    for name, n in lengths.items():
        rows = x[:, :n].copy()
        record[f"rfft {name} {n}"] = median_ms(lambda a: cp.fft.rfft(a, axis=-1), rows)
    for name, ms in record.items():
        print(f"{name:30s} {ms:8.3f} ms", flush=True)
    if args.out:
        with open(args.out, "w") as f:
            json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
