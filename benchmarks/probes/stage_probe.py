"""Three passes of the end-to-end run against variants that keep more loads in flight, at
thesis scale (300 rows): the random-phase spectrum (2.5 GB written), the summary pass over the
force deviations (2.5 GB read) and the PSD moments over the half spectra (2.5 GB read). Each
variant must give the same bits as the kernel it would replace; times are the kernel alone
(recorded launch), median of 7 after a warm-up.

    python benchmarks/probes/stage_probe.py --out stage_probe.json

Its runs: results/stage_probe_H200.json against the library's kernels of then (two hashes per
mode, one load in flight per thread in the summary pass, one row at a time in the moments);
_v2 after the summary pass took the four-load form and the moments the two-row form (still
one kernel for every mode); _v3 with the keyed spectrum and one moments kernel per mode; _v4
with eight loads in flight in the summary pass, four rows at a time in the moments, and a
variant of the spectrum kernel making two modes a thread (since then the library's form); _v5
after the summary pass's tail moved into a shared wp.func (finish_summary; 0.904 ms, unchanged). Its
"random_spectra (whole function)" includes fresh device allocations: this probe does not set
the memory pool's release threshold that every run sets (mdroll.devices).
"""
import argparse
import json
import math

import numpy as np
import warp as wp

from mdroll import Params
from mdroll.bench import timed
from mdroll.devices import to_warp
from mdroll.ensemble.lines import random_spectra
from mdroll.kernels import lines as line_kernels
from mdroll.kernels import spectra as kernels
from mdroll.kernels.spectra import FINAL_V, FINAL_Y, bin_value, response_bin, summary_add

DEVICE = "cuda:0"
P = Params(L=5.24288)
ROWS = 300
STEPS = 1_036_800


@wp.kernel
def series_summary_unrolled(deviation: wp.array2d(dtype=wp.float64), steps: int, threads: int, F_N: wp.float64,
                            inv_mass: wp.float64, weights: wp.array(dtype=wp.vec2d), with_state: int,
                            partial: wp.array3d(dtype=wp.float64)):
    r, t = wp.tid()
    sums = wp.vec4d()
    state = wp.vec2d()
    zero = wp.vec2d()
    s = t
    while s + 3 * threads < steps:
        u0 = deviation[r, s]
        u1 = deviation[r, s + threads]
        u2 = deviation[r, s + 2 * threads]
        u3 = deviation[r, s + 3 * threads]
        w0 = zero
        w1 = zero
        w2 = zero
        w3 = zero
        if with_state == 1:
            w0 = weights[steps - 1 - s]
            w1 = weights[steps - 1 - s - threads]
            w2 = weights[steps - 1 - s - 2 * threads]
            w3 = weights[steps - 1 - s - 3 * threads]
        sums, state = summary_add(u0, w0, F_N, sums, state)
        sums, state = summary_add(u1, w1, F_N, sums, state)
        sums, state = summary_add(u2, w2, F_N, sums, state)
        sums, state = summary_add(u3, w3, F_N, sums, state)
        s += 4 * threads
    kernels.finish_summary(deviation, weights, with_state, r, t, s, steps, threads, F_N, inv_mass, sums, state, partial)


@wp.func
def row_psds(force_spectrum: wp.array2d(dtype=wp.vec2d), states: wp.array2d(dtype=wp.float64), r: int, k: int,
             bins: int, steps: int, centre: kernels.ResponseBin, inv_mass: wp.float64, psd_scale: wp.float64):
    """Decoupled, no window: (force PSD, accel PSD) of row r at bin k."""
    b_force = bin_value(force_spectrum, r, k, bins, steps, 0, centre, inv_mass, wp.vec2d())
    state = wp.vec2d(states[r, FINAL_Y], states[r, FINAL_V])
    b_accel = bin_value(force_spectrum, r, k, bins, steps, 1, centre, inv_mass, state)
    return psd_scale * wp.vec2d(wp.dot(b_force, b_force), wp.dot(b_accel, b_accel))


@wp.kernel
def psd_moments_unrolled(force_spectrum: wp.array2d(dtype=wp.vec2d), states: wp.array2d(dtype=wp.float64),
                         steps: int, psd_scale: wp.float64, omega2: wp.float64, dt: wp.float64, inv_mass: wp.float64,
                         force_moments: wp.array(dtype=wp.vec2d), accel_moments: wp.array(dtype=wp.vec2d),
                         not_finite: wp.array(dtype=wp.int32)):
    k = wp.tid()
    rows = force_spectrum.shape[0]
    bins = force_spectrum.shape[1]
    centre = response_bin(k, steps, omega2, dt)
    shift = row_psds(force_spectrum, states, 0, k, bins, steps, centre, inv_mass, psd_scale)
    if not (wp.isfinite(shift[0]) and wp.isfinite(shift[1])):
        not_finite[0] = 1
    sums = wp.vec2d()
    squares = wp.vec2d()
    r = int(1)
    while r + 1 < rows:
        a = row_psds(force_spectrum, states, r, k, bins, steps, centre, inv_mass, psd_scale)
        b = row_psds(force_spectrum, states, r + 1, k, bins, steps, centre, inv_mass, psd_scale)
        if not (wp.isfinite(a[0]) and wp.isfinite(a[1])):
            not_finite[r] = 1
        if not (wp.isfinite(b[0]) and wp.isfinite(b[1])):
            not_finite[r + 1] = 1
        da = a - shift
        db = b - shift
        sums += da
        squares += wp.cw_mul(da, da)
        sums += db
        squares += wp.cw_mul(db, db)
        r += 2
    if r < rows:
        a = row_psds(force_spectrum, states, r, k, bins, steps, centre, inv_mass, psd_scale)
        if not (wp.isfinite(a[0]) and wp.isfinite(a[1])):
            not_finite[r] = 1
        da = a - shift
        sums += da
        squares += wp.cw_mul(da, da)
    count = wp.float64(rows)
    force_moments[k] = wp.vec2d(shift[0] + sums[0] / count, wp.max(squares[0] - sums[0] * sums[0] / count, wp.float64(0.0)))
    accel_moments[k] = wp.vec2d(shift[1] + sums[1] / count, wp.max(squares[1] - sums[1] * sums[1] / count, wp.float64(0.0)))


def kernel_ms(command):
    command.launch()
    return 1e3 * timed(command.launch, DEVICE, 7)[0]


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", default="stage_probe.json")
    parser.add_argument("--smoke", action="store_true", help="4 rows of a 0.05 m line on the CPU (checks only)")
    args = parser.parse_args()
    global DEVICE, P, ROWS, STEPS
    if args.smoke:
        DEVICE, P, ROWS, STEPS = "cpu", Params(L=0.05), 5, 10_001
    record = {}
    # random spectra: the whole function, the kernel alone, the kernel with per-row keys
    record["random_spectra (whole function)"] = 1e3 * timed(lambda: random_spectra(P, 5, ROWS, DEVICE), DEVICE, 7)[0]
    n = P.n_points
    bins = n // 2 + 1
    k_first, k_last = P.mode_range
    amplitudes = wp.empty(bins, dtype=wp.float64, device=DEVICE)
    wp.launch(line_kernels.mode_amplitudes, dim=bins, inputs=[k_first, k_last, -(P.H + 0.5), amplitudes], device=DEVICE)
    rows = wp.array(np.arange(ROWS), dtype=wp.int64, device=DEVICE)
    scales = wp.full(ROWS, 1.0, dtype=wp.float64, device=DEVICE)
    spectrum = wp.empty((ROWS, bins), dtype=wp.vec2d, device=DEVICE)
    nyquist = n // 2
    keys = wp.empty(ROWS, dtype=wp.uint64, device=DEVICE)
    wp.launch(line_kernels.line_scales, dim=ROWS, inputs=[rows, wp.uint64(5), amplitudes, nyquist, wp.ones(1, dtype=wp.float64, device=DEVICE),
              1.0, wp.empty(ROWS, dtype=wp.float64, device=DEVICE), keys], device=DEVICE)
    record["random_phase_spectrum (keyed)"] = kernel_ms(wp.launch(line_kernels.random_phase_spectrum, dim=(ROWS, (bins + 1) // 2),
        inputs=[keys, amplitudes, nyquist, scales, spectrum], device=DEVICE, record_cmd=True))
    del spectrum
    # summary pass
    rng = np.random.default_rng(0)
    deviation = to_warp(rng.standard_normal((ROWS, STEPS)) * 100.0, DEVICE)
    weights = wp.empty(STEPS, dtype=wp.vec2d, device=DEVICE)
    phi = 2.0 * math.asin(0.5 * P.omega_0 * P.dt)
    wp.launch(kernels.euler_impulse_response, dim=STEPS, inputs=[phi, P.dt, weights], device=DEVICE)
    for threads in ((512, 1024) if DEVICE != 'cpu' else (1, 3)):
        outs = {}
        for name, kernel in (("series_summary", kernels.series_summary), ("unrolled 4", series_summary_unrolled)):
            partial = wp.empty((ROWS, threads, kernels.SUM_COLUMNS), dtype=wp.float64, device=DEVICE)
            record[f"{name}, {threads} threads"] = kernel_ms(wp.launch(kernel, dim=(ROWS, threads),
                inputs=[deviation, STEPS, threads, P.F_N, 1.0 / P.m, weights, 1, partial], device=DEVICE, record_cmd=True))
            outs[name] = partial.numpy()
        record[f"summary identical, {threads}"] = bool(np.array_equal(outs["series_summary"], outs["unrolled 4"]))
        print(record, flush=True)
    del deviation
    # PSD moments (decoupled, no window)
    spectrum = wp.array(rng.standard_normal((ROWS, STEPS // 2 + 1, 2)), dtype=wp.vec2d, device=DEVICE)
    states = wp.array(rng.standard_normal((ROWS, kernels.SUM_COLUMNS)) * 1e-6, dtype=wp.float64, device=DEVICE)
    outs = {}
    scale = P.dx / (2.0 * math.pi * STEPS)
    variants = (("psd_moments", kernels.psd_moments_kernel(True, False)), ("unrolled 2", psd_moments_unrolled),
                ("psd_moments, Hann window", kernels.psd_moments_kernel(True, True)))
    for name, kernel in variants:
        fm = wp.empty(STEPS // 2 + 1, dtype=wp.vec2d, device=DEVICE)
        am = wp.empty_like(fm)
        bad = wp.zeros(ROWS, dtype=wp.int32, device=DEVICE)
        if kernel is psd_moments_unrolled:
            inputs = [spectrum, states, STEPS, scale, P.omega_0**2, P.dt, 1.0 / P.m, fm, am, bad]
        else:
            inputs = [spectrum, spectrum, states, STEPS, scale, P.omega_0**2, P.dt, 1.0 / P.m, fm, am, bad]
        record[name] = kernel_ms(wp.launch(kernel, dim=fm.shape[0], inputs=inputs, device=DEVICE, record_cmd=True))
        outs[name] = (fm.numpy(), am.numpy())
    record["moments identical"] = bool(all(np.array_equal(a, b) for a, b in zip(outs["psd_moments"], outs["unrolled 2"])))
    print(json.dumps(record, indent=1), flush=True)
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
