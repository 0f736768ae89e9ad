"""Batched real FFTs along the last axis: pyfftw on the CPU, cuFFT (CuPy) on CUDA.

A CUDA run never falls back to a CPU FFT. Both follow NumPy's normalization: ``rfft`` is
unnormalized, ``irfft`` divides by n.

On the CPU each row is transformed by the same cached one-row plan, so a row's result does not
depend on how many rows travel with it (FFTW's plans for different batch counts round
differently, which would break batch-independent ensembles beyond 1e-12).
"""

from __future__ import annotations

import functools
import os

import numpy as np

from ..devices import cupy_stream, cupy_view, is_cuda, warp


@functools.cache
def _pyfftw():
    import pyfftw
    import pyfftw.interfaces.cache
    import pyfftw.interfaces.numpy_fft

    pyfftw.interfaces.cache.enable()
    pyfftw.interfaces.cache.set_keepalive_time(60.0)
    return pyfftw.interfaces.numpy_fft


def fast_length(limit: int) -> int:
    """The largest ``2^a 3^b 5^c <= limit`` (limit >= 1): a length both cuFFT and FFTW transform
    at full speed. On an H200, cuFFT's real FFT of 300 rows of 1,046,492 = 4 x 397 x 659 points
    took 17.5 ms, of 1,036,800 = 2^10 3^4 5^2 points 5.3 ms (benchmarks/results/cufft_probe_H200.json)."""
    if limit < 1:
        raise ValueError(f"limit = {limit!r}: it must be at least 1")
    best = 1
    power5 = 1
    while power5 <= limit:
        power35 = power5
        while power35 <= limit:
            # the largest power of two times power35 that fits
            best = max(best, power35 << ((limit // power35).bit_length() - 1))
            power35 *= 3
        power5 *= 5
    return best


def _threads() -> int:
    return max(1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


def irfft_rows(spectrum, n: int, device: str):
    """Inverse real FFT of each row of a half spectrum (complex, shape (R, n//2+1)) to length n.

    ``spectrum`` is a Warp ``vec2d`` array (or complex NumPy/CuPy array) on ``device``; on CUDA
    the transform may overwrite it (no copy first: 5.8 instead of 7.0 ms at 300 x 2^20 on an
    H200). Returns a float64 NumPy array on the CPU, a float64 Warp array on CUDA.
    """
    wp = warp()
    if is_cuda(device):
        import cupy
        import cupyx.scipy.fft

        with cupy_stream(device):
            x = cupy_view(spectrum)
            if x.dtype != cupy.complex128:
                x = x.view(cupy.complex128).reshape(x.shape[0], -1)
            out = cupyx.scipy.fft.irfft(x, n=n, axis=-1, overwrite_x=True)
        return wp.from_dlpack(out)
    x = spectrum.numpy() if isinstance(spectrum, wp.array) else np.asarray(spectrum)
    if x.dtype != np.complex128:
        x = x.view(np.complex128).reshape(x.shape[0], -1)
    fft = _pyfftw()
    out = np.empty((x.shape[0], n))
    for i, row in enumerate(x):
        out[i] = fft.irfft(row, n=n, threads=_threads(), planner_effort="FFTW_ESTIMATE")
    return out


def rfft_rows(x, device: str):
    """Forward real FFT of each row (float64, shape (R, n)); NumPy on the CPU, CuPy on CUDA."""
    if is_cuda(device):
        import cupy

        with cupy_stream(device):
            return cupy.fft.rfft(cupy_view(x), axis=-1)
    x = x.numpy() if isinstance(x, warp().array) else np.asarray(x)
    fft = _pyfftw()
    out = np.empty((x.shape[0], x.shape[1] // 2 + 1), dtype=np.complex128)
    for i, row in enumerate(x):
        out[i] = fft.rfft(row, threads=_threads(), planner_effort="FFTW_ESTIMATE")
    return out
