"""Why the random spectra of 300 x 2^20 lines take ~8 ms: the kernels of
mdroll.ensemble.lines.random_spectra timed apart, and variants of the per-element kernel
without the trigonometry or without the hash; and the kernels of the response stage
(mdroll.ensemble.spectra.series_sums). Medians of 10 (ms), after a warm-up."""
import json
import statistics
import sys
import time

import numpy as np
import warp as wp

from mdroll import Params
from mdroll.kernels.lines import (TWO_PI, line_scales, mode_amplitudes, random_phase_spectrum, realization_key,
                                 uniform_from_key)


@wp.kernel
def no_trig(realizations: wp.array(dtype=wp.int64), seed: wp.uint64, amplitudes: wp.array(dtype=wp.float64),
            spectrum: wp.array2d(dtype=wp.vec2d)):
    r, k = wp.tid()
    u = uniform_from_key(realization_key(seed, realizations[r]), k)
    spectrum[r, k] = wp.vec2d(amplitudes[k] * u, u)


@wp.kernel
def no_hash(amplitudes: wp.array(dtype=wp.float64), spectrum: wp.array2d(dtype=wp.vec2d)):
    r, k = wp.tid()
    phase = TWO_PI * wp.float64(k) * wp.float64(1e-6)
    spectrum[r, k] = wp.vec2d(amplitudes[k] * wp.cos(phase), amplitudes[k] * wp.sin(phase))


@wp.kernel
def write_only(amplitudes: wp.array(dtype=wp.float64), spectrum: wp.array2d(dtype=wp.vec2d)):
    r, k = wp.tid()
    spectrum[r, k] = wp.vec2d(amplitudes[k], amplitudes[k])


def main():
    device = "cuda:0"
    p = Params(L=5.24288, n_real=300)
    n = p.n_points
    bins = n // 2 + 1
    k_first, k_last = p.mode_range
    rows = wp.array(np.arange(300), dtype=wp.int64, device=device)
    amplitudes = wp.empty(bins, dtype=wp.float64, device=device)
    scales = wp.empty(300, dtype=wp.float64, device=device)
    keys = wp.empty(300, dtype=wp.uint64, device=device)
    spectrum = wp.empty((300, bins), dtype=wp.vec2d, device=device)
    cases = {
        "mode_amplitudes": lambda: wp.launch(mode_amplitudes, dim=bins, inputs=[k_first, k_last, -(p.H + 0.5), amplitudes], device=device),
        "line_scales": lambda: wp.launch(line_scales, dim=300, inputs=[rows, wp.uint64(0), amplitudes, n // 2, 1.0, 1.0, scales, keys], device=device),
        "random_phase_spectrum": lambda: wp.launch(random_phase_spectrum, dim=(300, (bins + 1) // 2), inputs=[keys, amplitudes, n // 2, scales, spectrum], device=device),
        "no trigonometry": lambda: wp.launch(no_trig, dim=(300, bins), inputs=[rows, wp.uint64(0), amplitudes, spectrum], device=device),
        "no hash": lambda: wp.launch(no_hash, dim=(300, bins), inputs=[amplitudes, spectrum], device=device),
        "write only": lambda: wp.launch(write_only, dim=(300, bins), inputs=[amplitudes, spectrum], device=device),
    }
    from mdroll.kernels.spectra import SUMMARY_THREADS, add_partials, euler_impulse_response, series_summary

    steps = 1_036_800
    force = wp.array(np.full((300, steps), p.F_N), dtype=wp.float64, device=device)
    weights = wp.empty(steps, dtype=wp.vec2d, device=device)
    partial = wp.empty((300, SUMMARY_THREADS, 6), dtype=wp.float64, device=device)
    sums = wp.empty((300, 6), dtype=wp.float64, device=device)
    cases["euler_impulse_response"] = lambda: wp.launch(euler_impulse_response, dim=steps, inputs=[1e-4, p.dt, weights], device=device)
    cases["series_summary"] = lambda: wp.launch(series_summary, dim=(300, SUMMARY_THREADS), inputs=[force, steps, SUMMARY_THREADS, p.F_N, 1.0 / p.m, weights, 1, partial], device=device)
    cases["add_partials"] = lambda: wp.launch(add_partials, dim=(300, 6), inputs=[partial, SUMMARY_THREADS, sums], device=device)
    cases["sums to host"] = lambda: sums.numpy()
    out = {}
    for name, fn in cases.items():
        fn()
        wp.synchronize_device(device)
        runs = []
        for _ in range(10):
            t0 = time.perf_counter()
            fn()
            wp.synchronize_device(device)
            runs.append(time.perf_counter() - t0)
        out[name] = statistics.median(runs) * 1e3
        print(f"{name:<25} {out[name]:8.3f} ms", flush=True)
    json.dump(out, open(sys.argv[1], "w"), indent=1)


if __name__ == "__main__":
    main()
