"""CuPy-only timings behind the generate and build stages (300 x 2^20 float64, H200): the inverse
FFT with and without leaving the input to be overwritten, and prefix sums per row vs over the
flattened batch (CUB). Writes a JSON of medians (ms) to argv[1]."""
import json
import sys

import cupy as cp
import cupyx.scipy.fft as cufft
import numpy as np
from cupyx.profiler import benchmark

R, n = 300, 2**20
res = {}


def t(name, f, *a):
    ms = float(np.median(benchmark(f, a, n_repeat=20, n_warmup=3).gpu_times)) * 1e3
    res[name] = ms
    print(f"{name:50s} {ms:8.3f} ms", flush=True)


x = cp.random.standard_normal((R, n))
X = cp.fft.rfft(x, axis=-1)
t("cupy.fft.irfft", lambda a: cp.fft.irfft(a, n=n, axis=-1), X)
t("cupyx.scipy.fft.irfft overwrite_x", lambda a: cufft.irfft(a, n=n, axis=-1, overwrite_x=True), X.copy())
t("copy of the half spectrum", lambda a: a.copy(), X)
t("cumsum axis=1", lambda a: cp.cumsum(a, axis=1), x)
flat = cp.empty(R * n + 1)
t("cumsum of the flattened batch (out=)", lambda a: cp.cumsum(a.ravel(), out=flat[1:]), x)
t("min and max per row", lambda a: (a.min(axis=1), a.max(axis=1)), x)
json.dump(res, open(sys.argv[1], "w"), indent=1)
