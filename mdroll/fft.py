"""Batched real FFTs along the last axis: pyfftw on the CPU, cuFFT (CuPy) on CUDA.

A CUDA run never falls back to a CPU FFT. Neither direction is normalized: ``rfft`` follows
NumPy, ``irfft`` is NumPy's times n (its callers build spectra already scaled).

On the CPU each row is transformed by the same cached one-row plan, so a row's result does not
depend on how many rows travel with it (FFTW's plans for different batch counts round
differently, which would break batch-independent ensembles beyond 1e-12). On CUDA every batch
goes through one cached cuFFT plan of :func:`cuda_plan_rows` rows per transform and length, its
last rows padded: the same holds, and the plans' work areas (each up to its rows' size) stay the
same whatever the sizes of a run's batches, so that repeated runs find the same free memory.
"""

from __future__ import annotations

import contextlib
import functools
import threading

import numpy as np

from .devices import cpu_cores, cupy_stream, cupy_view, is_cuda, warp
from . import buffers


#: FFTW plans kept per Python thread (each with its own aligned rows to fall back on).
CPU_PLANS = 4
_plans = threading.local()


def _cpu_plan(kind: str, n: int):
    """This thread's FFTW plan of one row, ``"irfft"`` (half spectrum of n // 2 + 1 -> n reals)
    or ``"rfft"`` (n reals -> half spectrum), on ``_threads()`` FFTW threads; run by ``execute``,
    which never scales (pyfftw's ``__call__`` would).

    Planned as pyfftw's ``interfaces.numpy_fft`` plans them (FFTW_ESTIMATE, input preserved,
    SIMD-aligned rows), so a line is the same to the bit as through those interfaces (and
    whatever the FFTW threads). Kept per thread: a plan runs on one thread's rows at a time."""
    import pyfftw

    plans = _plans.__dict__.setdefault("plans", {})
    key = (kind, n, _threads())
    plan = plans.pop(key, None)
    if plan is None:
        real = pyfftw.empty_aligned(n, dtype=np.float64)
        half = pyfftw.empty_aligned(n // 2 + 1, dtype=np.complex128)
        if kind == "irfft":
            plan = pyfftw.FFTW(half, real, direction="FFTW_BACKWARD", flags=("FFTW_ESTIMATE",), threads=key[2])
        else:
            plan = pyfftw.FFTW(real, half, direction="FFTW_FORWARD", flags=("FFTW_ESTIMATE",), threads=key[2])
        plan = (plan, plan.input_array, plan.output_array, kind == "rfft")
        if len(plans) >= CPU_PLANS:
            del plans[next(iter(plans))]
    plans[key] = plan  # most recently used last
    return plan


def _cpu_rows(plan, x: np.ndarray, out: np.ndarray) -> None:
    """``out[i] = transform(x[i])`` for each row by a plan of :func:`_cpu_plan`: in place of the
    caller's rows where they are aligned as the plan's (no copy), else through the plan's own.
    The forward plan always reads a copy in its own row: the copy streams the row into the cache
    ahead of FFTW's strided passes, which then run faster than on the caller's row."""
    plan, own_in, own_out, copy_in = plan
    alignment = plan.input_alignment
    for src, dst in zip(x, out):
        src_fits = not copy_in and src.ctypes.data % alignment == 0 and src.strides == own_in.strides
        dst_fits = dst.ctypes.data % plan.output_alignment == 0 and dst.strides == own_out.strides
        if not src_fits:
            own_in[:] = src
        plan.update_arrays(src if src_fits else own_in, dst if dst_fits else own_out)
        plan.execute()
        if not dst_fits:
            dst[:] = own_out


def fast_length(limit: int) -> int:
    """The largest ``2^a 3^b 5^c <= limit`` (limit >= 1): a length both cuFFT and FFTW transform
    at full speed; a length with large prime factors takes several times longer
    (docs/performance.md, "FFT lengths")."""
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


#: Per Python thread: the FFTW threads of its CPU transforms (unset: every core).
_fftw_threads = threading.local()


@contextlib.contextmanager
def fftw_threads(count: int):
    """Within the block, this Python thread's CPU transforms use ``count`` FFTW threads: the
    pipeline's CPU workers each transform their own rows on one (:func:`mdroll.run_ensemble`)."""
    previous = getattr(_fftw_threads, "count", None)
    _fftw_threads.count = count
    try:
        yield
    finally:
        _fftw_threads.count = previous


def _threads() -> int:
    return getattr(_fftw_threads, "count", None) or cpu_cores()


#: Rows one cuFFT plan transforms at once (module docstring), and the points it may hold: enough
#: to keep the device busy on lines of 2^12 points and more; fewer rows on lines longer than 2^20
#: points, so that a plan's work area and the padded scratch stay within 2^25 points each.
CUDA_FFT_ROWS = 32
CUDA_FFT_POINTS = 2**25


def cuda_plan_rows(n: int) -> int:
    """Rows a cuFFT plan of length n transforms at once: :data:`CUDA_FFT_ROWS`, fewer (at least
    one) where they would hold more than :data:`CUDA_FFT_POINTS` points."""
    return max(1, min(CUDA_FFT_ROWS, CUDA_FFT_POINTS // n))


@functools.lru_cache(maxsize=8)
def _cuda_plan(n: int, fft_type: int, ordinal: int):
    """The cuFFT plan of :func:`cuda_plan_rows` contiguous transforms of length n on GPU
    ``ordinal``, kept for every later batch (its work area stays allocated while it is cached)."""
    import cupy

    with cupy.cuda.Device(ordinal):
        return cupy.cuda.cufft.Plan1d(n, fft_type, cuda_plan_rows(n))


def _cuda_rows(x, out, n: int, fft_type: int, direction: int, ordinal: int) -> None:
    """``out[i] = transform(x[i])`` for each row (CuPy arrays, C-contiguous), by
    :func:`_cuda_plan` :func:`cuda_plan_rows` rows at a time, the last rows through a padded
    scratch of that many; on the current stream. A C2R transform overwrites its input."""
    import cupy

    plan, step = _cuda_plan(n, fft_type, ordinal), cuda_plan_rows(n)
    rows = x.shape[0]
    whole = rows - rows % step
    for i in range(0, whole, step):
        plan.fft(x[i:i + step], out[i:i + step], direction)
    if whole < rows:
        source = cupy.zeros((step, x.shape[1]), dtype=x.dtype)
        source[:rows - whole] = x[whole:]
        target = cupy.empty((step, out.shape[1]), dtype=out.dtype)
        plan.fft(source, target, direction)
        out[whole:] = target[:rows - whole]


def irfft_rows(spectrum, n: int, device: str):
    """Unnormalized inverse real FFT of each row of a half spectrum (complex, shape (R, n//2+1)):
    ``h_j = sum_{k=-n/2}^{n/2} X_k exp(2 pi i j k / n)`` with ``X_{-k} = conj(X_k)``, no 1/n
    (the caller scales the spectrum; physics.md section 3's sum as written).

    ``spectrum`` is a Warp ``vec2d`` array (or complex NumPy/CuPy array) on ``device``; on CUDA
    the transform overwrites it. On CUDA the cached cuFFT plan runs on the spectrum's own memory
    (:func:`_cuda_rows`): CuPy's ``irfft`` would first copy a view like this one, and scale by 1/n
    in a second pass (docs/performance.md, "Rough lines").
    Returns a float64 NumPy array on the CPU (within :func:`mdroll.buffers.reused`, the
    thread's buffer "lines"), a float64 Warp array on CUDA.
    """
    wp = warp()
    if is_cuda(device):
        import cupy
        from cupy.cuda import cufft

        with cupy_stream(device):
            x = cupy_view(spectrum)
            if x.dtype != cupy.complex128:
                x = x.view(cupy.complex128).reshape(x.shape[0], -1)
            if x.shape[1] != n // 2 + 1 or not x.flags.c_contiguous:
                raise ValueError(f"irfft_rows needs a contiguous (R, {n // 2 + 1}) half spectrum, got {x.shape}")
            out = cupy.empty((x.shape[0], n), dtype=cupy.float64)
            _cuda_rows(x, out, n, cufft.CUFFT_Z2D, cufft.CUFFT_INVERSE, wp.get_device(device).ordinal)
        return wp.from_dlpack(out)
    x = spectrum.numpy() if isinstance(spectrum, wp.array) else np.asarray(spectrum)
    if x.dtype != np.complex128:
        x = x.view(np.complex128)[..., 0]
    out = buffers.empty("lines", (x.shape[0], n), wp.float64, "cpu").numpy()
    _cpu_rows(_cpu_plan("irfft", n), x, out)
    return out


def rfft_rows(x, device: str, name: str = "half spectrum"):
    """Forward real FFT of each row (float64, shape (R, n)): complex128 (R, n // 2 + 1); NumPy on
    the CPU (within :func:`mdroll.buffers.reused`, the thread's buffer ``name``), CuPy
    on CUDA."""
    if is_cuda(device):
        import cupy
        from cupy.cuda import cufft

        with cupy_stream(device):
            x = cupy.ascontiguousarray(cupy_view(x), dtype=cupy.float64)
            rows, n = x.shape
            out = cupy.empty((rows, n // 2 + 1), dtype=cupy.complex128)
            _cuda_rows(x, out, n, cufft.CUFFT_D2Z, cufft.CUFFT_FORWARD, x.device.id)
            return out
    wp = warp()
    x = x.numpy() if isinstance(x, wp.array) else np.asarray(x)
    rows, n = x.shape
    out = buffers.empty(name, (rows, n // 2 + 1), wp.vec2d, "cpu", aligned=True).numpy().view(np.complex128)[..., 0]
    _cpu_rows(_cpu_plan("rfft", n), x, out)
    return out
