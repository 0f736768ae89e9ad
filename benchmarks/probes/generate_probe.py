"""Where the generate stage's time goes at thesis scale (300 x 2^20): each step of
``mdroll.ensemble.lines.random_spectra`` and the inverse FFT, timed alone (device synchronized
around each, median of 7 after a warm-up), against the whole function.

    python benchmarks/probes/generate_probe.py --out generate_probe.json
"""
import argparse
import json

import numpy as np
import warp as wp

from mdroll import Params
from mdroll.bench import timed
from mdroll.devices import resolve_device
from mdroll.ensemble.fft import irfft_rows
from mdroll.ensemble.lines import random_spectra
from mdroll.kernels.lines import line_scales, mode_amplitudes, random_phase_spectrum

DEVICE = "cuda:0"
P = Params(L=5.24288)
ROWS = 300


def ms(fn):
    fn()
    return round(1e3 * timed(fn, DEVICE, 7)[0], 3)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", default="generate_probe.json")
    args = parser.parse_args()
    resolve_device(DEVICE)  # as every run does first: the memory pool keeps freed blocks (devices.py)
    n = P.n_points
    bins = n // 2 + 1
    k_first, k_last = P.mode_range
    indices = np.arange(ROWS, dtype=np.int64)
    amplitudes = wp.empty(bins, dtype=wp.float64, device=DEVICE)
    total = wp.empty(1, dtype=wp.float64, device=DEVICE)
    rows = wp.array(indices, dtype=wp.int64, device=DEVICE)
    scales = wp.empty(ROWS, dtype=wp.float64, device=DEVICE)
    keys = wp.empty(ROWS, dtype=wp.uint64, device=DEVICE)
    spectrum = wp.empty((ROWS, bins), dtype=wp.vec2d, device=DEVICE)
    record = {
        "Params.mode_range (host)": ms(lambda: P.mode_range),
        "mode_amplitudes": ms(lambda: wp.launch(mode_amplitudes, dim=bins, inputs=[k_first, k_last, -(P.H + 0.5), amplitudes],
                                                device=DEVICE)),
        "array_inner": ms(lambda: wp.utils.array_inner(amplitudes, amplitudes, out=total)),
        "realization indices to the device": ms(lambda: wp.array(indices, dtype=wp.int64, device=DEVICE)),
        "line_scales": ms(lambda: wp.launch(line_scales, dim=ROWS, inputs=[rows, wp.uint64(5), amplitudes, n // 2, total,
                                                                          P.h0, scales, keys], device=DEVICE)),
        "empty spectrum (2.5 GB)": ms(lambda: wp.empty((ROWS, bins), dtype=wp.vec2d, device=DEVICE)),
        "random_phase_spectrum": ms(lambda: wp.launch(random_phase_spectrum, dim=(ROWS, (bins + 1) // 2),
                                                      inputs=[keys, amplitudes, n // 2, scales, spectrum],
                                                      device=DEVICE)),
        "random_spectra (whole)": ms(lambda: random_spectra(P, 5, ROWS, DEVICE)),
        "random_spectra + irfft_rows": ms(lambda: irfft_rows(random_spectra(P, 5, ROWS, DEVICE), n, DEVICE)),
    }
    del spectrum
    record["random_spectra + irfft_rows, twice in a row (second)"] = ms(
        lambda: [irfft_rows(random_spectra(P, 5, ROWS, DEVICE), n, DEVICE) for _ in range(2)]) / 2
    print(json.dumps(record, indent=1), flush=True)
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
