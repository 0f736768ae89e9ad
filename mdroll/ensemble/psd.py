"""Power spectral densities of force and acceleration series, and their running ensemble moments.

Convention (physics.md sections 3 and 6): for a series F_s at x_s = s dx, s = 0..N-1, of length
L = N dx, ``B(q_k) = (1/N) sum_s (F_s - mean F) w_s exp(-i q_k x_s)`` and the two-sided PSD
``C(q_k) = L / (2 pi) |B(q_k)|^2`` at ``q_k = 2 pi k / L`` (rad/m), k = 0..N/2. The frequency
form is ``C(omega) = C(q) / v0`` at ``omega = q v0``. ``w`` is 1 (default) or a Hann window
scaled to mean(w^2) = 1, which keeps the total power.
"""

from __future__ import annotations

import functools

import numpy as np

from ..devices import array_module, cupy_stream, cupy_view, is_cuda, queue_on, to_warp, warp
from ..physics import TWO_PI, euler_resonance_phase, hann_window, psd_from_transform
from ..params import Params
from ..kernels.moments import (SUM_COLUMNS, SUMMARY_THREADS, ResponseBin, add_partials, euler_impulse_response,
                              merge_moments, psd_moments_kernel, response_table, series_summary)
from ..fft import rfft_rows


def wavenumbers(steps: int, dx: float, xp=np):
    """``q_k = 2 pi k / (N dx)`` (rad/m) for k = 0..N/2, as a NumPy (default) or CuPy (``xp``) array."""
    return TWO_PI * xp.arange(steps // 2 + 1) / (steps * dx)


def psd_rows(series, dx: float, device: str, window: bool = False):
    """Two-sided PSD of each row of ``series`` (R, N), in (unit^2 m); NumPy on the CPU, CuPy on CUDA."""
    if is_cuda(device):
        import cupy as xp

        with cupy_stream(device):
            x = cupy_view(series)
            x = x - x.mean(axis=1, keepdims=True)
            if window:
                x = x * hann_window(x.shape[1], xp)
            return psd_from_transform(rfft_rows(x, device), x.shape[1], dx)
    x = np.asarray(series.numpy() if hasattr(series, "numpy") else series)
    x = x - x.mean(axis=1, keepdims=True)
    if window:
        x = x * hann_window(x.shape[1], np)
    return psd_from_transform(rfft_rows(x, device), x.shape[1], dx)


def array_rows(array, device: str):
    """A NumPy (CPU) or CuPy (CUDA) view of a Warp, NumPy or CuPy array."""
    if is_cuda(device):
        return cupy_view(array)
    return array.numpy() if hasattr(array, "numpy") else np.asarray(array)


def to_host(array, page_locked: bool = False, wait: bool = True) -> np.ndarray:
    """A NumPy array from a NumPy, CuPy or Warp array. ``page_locked``: a CuPy array lands in
    page-locked (pinned) host memory from CuPy's pool, which the device writes at full link
    speed; the returned array keeps that memory until it is freed. ``wait=False`` (with
    ``page_locked``): the copy is only queued on the current stream, and the array may be read
    once the host has waited for that stream."""
    if hasattr(array, "get"):
        if not page_locked:
            return array.get()
        import cupy

        memory = cupy.cuda.alloc_pinned_memory(array.nbytes)
        out = np.frombuffer(memory, array.dtype, array.size).reshape(array.shape)
        return array.get(out=out, blocking=wait)
    if hasattr(array, "numpy"):
        return array.numpy()
    return np.asarray(array)


def complex_rows(spectrum, device: str):
    """A (R, K) ``wp.vec2d`` Warp view of a complex128 NumPy (CPU) or CuPy (CUDA) array."""
    wp = warp()
    rows, bins = spectrum.shape
    if is_cuda(device):
        import cupy

        return wp.from_dlpack(spectrum.view(cupy.float64).reshape(rows, bins, 2), dtype=wp.vec2d)
    if spectrum.strides[-1] != spectrum.itemsize:
        spectrum = np.ascontiguousarray(spectrum)
    # a view, also of rows padded to alignment (the FFT's buffers, :mod:`mdroll.buffers`)
    return wp.array(spectrum.view(np.float64).reshape(rows, bins, 2), dtype=wp.vec2d, device="cpu", copy=False)


def series_sums(deviation, params: Params, device: str, decoupled: bool):
    """Per row of ``deviation`` (R, N; the force less F_N, ``u = F - F_N``, N), one pass that
    only reads: the (R, SUM_COLUMNS) Warp array on ``device`` (nothing waits for it) of
    ``sum u`` (N), ``sum u^2`` (N^2), steps with
    contact lost (F <= 0), non-finite steps and, when ``decoupled``, the state (y_N (m),
    y'_N (m/s)) after the last step of the decoupled wheel started at rest (section 5.1; zeros
    otherwise). See :func:`mdroll.kernels.moments.series_summary`."""
    wp = warp()
    rows, steps = deviation.shape
    threads = SUMMARY_THREADS if is_cuda(device) else 1
    if decoupled:
        weights = _impulse_response(steps, euler_resonance_phase(params.omega_0, params.dt), params.dt, device)
    else:
        weights = wp.empty(1, dtype=wp.vec2d, device=device)
    partial = wp.empty((rows, threads, SUM_COLUMNS), dtype=wp.float64, device=device)
    wp.launch(series_summary, dim=(rows, threads),
              inputs=[deviation, steps, threads, params.F_N, 1.0 / params.m, weights, int(decoupled), partial], device=device)
    sums = wp.empty((rows, SUM_COLUMNS), dtype=wp.float64, device=device)
    wp.launch(add_partials, dim=(rows, SUM_COLUMNS), inputs=[partial, threads, sums], device=device)
    return sums


@functools.lru_cache(maxsize=4)
def _impulse_response(steps: int, phi: float, dt: float, device: str):
    """The decoupled wheel's ``A^m b`` for m = 0..steps-1 (:func:`mdroll.kernels.moments.euler_impulse_response`;
    ``phi`` rad, ``dt`` s) as a ``wp.vec2d`` array on ``device``: the same for every batch of a
    run, so made once (three sines a step)."""
    wp = warp()
    weights = wp.empty(steps, dtype=wp.vec2d, device=device)
    wp.launch(euler_impulse_response, dim=steps, inputs=[phi, dt, weights], device=device)
    return weights


@functools.lru_cache(maxsize=4)
def _responses(steps: int, omega2: float, dt: float, device: str):
    """The decoupled wheel's response at each bin of a half spectrum of ``steps`` steps
    (:func:`mdroll.kernels.moments.response_table`; ``omega2`` rad^2/s^2, ``dt`` s) on
    ``device``: the same for every batch of a run, so made once."""
    wp = warp()
    table = wp.empty(steps // 2 + 1, dtype=ResponseBin, device=device)
    wp.launch(response_table, dim=table.shape, inputs=[steps, omega2, dt, table], device=device)
    return table


@functools.lru_cache(maxsize=4)
def _no_responses(device: str):
    """A one-bin table for the coupled mode's moments, which read none."""
    return warp().zeros(1, dtype=ResponseBin, device=device)


#: Rows whose force and acceleration spectra the coupled mode transforms at a time
#: (:func:`psd_moments_of_batch`): its spectra's memory stays that of this many rows whatever the
#: batch (:data:`~mdroll.ensemble.batching.COUPLED_BYTES_PER_POINT`).
SPECTRA_ROWS = 128


def psd_moments_of_batch(force, accel, sums, params: Params, device: str, window: bool = False):
    """Per-bin mean and M2 over the rows of the force and acceleration PSDs (section 6).

    One real FFT of each force row (and of each acceleration row when ``accel`` is given, the
    coupled mode); without ``accel`` the acceleration's spectrum is the decoupled wheel's,
    computed from the force's and the final states in ``sums`` (:func:`series_sums`) bin by bin
    (:class:`mdroll.kernels.moments.ResponseBin`): exact, and no acceleration series is needed.
    With ``accel`` the rows go :data:`SPECTRA_ROWS` at a time, their moments merged in order
    (:class:`RunningMoments`; one part: the same to the bit).

    ``sums`` may be on the host or on ``device``. Returns ``(force (K, 2), accel (K, 2),
    not_finite (R,))``: columns mean and M2, and a flag per row whose PSD has NaN or infinity,
    all where the work ran (NumPy on the CPU, CuPy on CUDA; nothing waits for them).
    """
    rows = force.shape[0]
    if accel is None or rows <= SPECTRA_ROWS:
        return _moments_of_rows(force, accel, sums, params, device, window)
    ends = [(i, min(i + SPECTRA_ROWS, rows)) for i in range(0, rows, SPECTRA_ROWS)]
    parts = [_moments_of_rows(force[i:j], accel[i:j], sums[i:j], params, device, window) for i, j in ends]
    xp = array_module(parts[0][0])
    merged = []
    with queue_on(device):
        for column in range(2):
            moments = RunningMoments(parts[0][column].shape[0], xp)
            for (i, j), part in zip(ends, parts):
                moments.add_moments(j - i, part[column])
            merged.append(moments.columns())
        return merged[0], merged[1], xp.concatenate([part[2] for part in parts])


def _moments_of_rows(force, accel, sums, params: Params, device: str, window: bool):
    """:func:`psd_moments_of_batch` of the rows given, in one part."""
    wp = warp()
    rows, steps = force.shape
    force_spectrum = complex_rows(rfft_rows(force, device, "force spectrum"), device)
    accel_spectrum = force_spectrum if accel is None else complex_rows(rfft_rows(accel, device, "accel spectrum"), device)
    bins = force_spectrum.shape[1]
    force_moments = wp.empty(bins, dtype=wp.vec2d, device=device)
    accel_moments = wp.empty(bins, dtype=wp.vec2d, device=device)
    not_finite = wp.zeros(rows, dtype=wp.int32, device=device)
    responses = _responses(steps, params.omega_0**2, params.dt, device) if accel is None else _no_responses(device)
    wp.launch(
        psd_moments_kernel(accel is None, bool(window)),
        dim=bins,
        inputs=[force_spectrum, accel_spectrum, to_warp(sums, device), steps,
                params.dx / (TWO_PI * steps), responses, 1.0 / params.m,
                force_moments, accel_moments, not_finite],
        device=device,
    )
    force_view, accel_view = (array_rows(m, device).reshape(bins, 2) for m in (force_moments, accel_moments))
    return force_view, accel_view, array_rows(not_finite, device)


class RunningMoments:
    """Per-bin count, mean and sum of squared deviations, merged batch by batch (Chan et al.).

    Memory is one row of bins whatever the number of realizations; the rows stay on the device
    they come from (NumPy or CuPy), and ``mean`` / ``stderr`` are returned on the host.
    """

    def __init__(self, bins: int, xp=np):
        self.count = 0
        self._mean = xp.zeros(bins)
        self._m2 = xp.zeros(bins)

    @property
    def mean(self) -> np.ndarray:
        return to_host(self._mean)

    @property
    def m2(self) -> np.ndarray:
        return to_host(self._m2)

    def move_to(self, xp) -> None:
        """Keep the moments in ``xp``'s memory (``numpy`` or ``cupy``) from now on."""
        if array_module(self._mean) is not xp:
            self._mean, self._m2 = xp.asarray(to_host(self._mean)), xp.asarray(to_host(self._m2))

    def add(self, rows) -> None:
        """Merge a batch of rows (realizations x bins)."""
        mean_b = rows.mean(axis=0)
        self.merge(rows.shape[0], mean_b, ((rows - mean_b) ** 2).sum(axis=0))

    def add_moments(self, n_b: int, moments) -> None:
        """Merge a batch's (bins, 2) columns of mean and M2 (:func:`psd_moments_of_batch`). On
        the host in one pass (:func:`mdroll.kernels.moments.merge_moments`), not NumPy's seven,
        for every part of the realizations of a CPU run."""
        if array_module(self._mean) is not np or n_b == 0:
            self.merge(n_b, moments[:, 0], moments[:, 1])
            return
        wp = warp()
        columns = wp.array(np.ascontiguousarray(moments).view(np.float64).reshape(-1, 2), dtype=wp.vec2d, device="cpu",
                           copy=False)
        own = [wp.array(a, dtype=wp.float64, device="cpu", copy=False) for a in (self._mean, self._m2)]
        wp.launch(merge_moments, dim=columns.shape, inputs=[float(self.count), float(n_b), *own, columns], device="cpu")
        self.count += n_b

    def merge(self, n_b: int, mean_b, m2_b) -> None:
        """Merge the moments of another set of ``n_b`` samples (Chan et al.): count, mean, M2."""
        if n_b == 0:
            return
        xp = array_module(self._mean)
        mean_b, m2_b = xp.asarray(mean_b), xp.asarray(m2_b)
        total = self.count + n_b
        delta = mean_b - self._mean
        # in place, in the order of mean + delta n_b / total and (M2 + M2_b) + delta^2 count n_b / total
        self._mean += delta * (n_b / total)
        self._m2 += m2_b
        delta *= delta
        delta *= self.count * n_b / total
        self._m2 += delta
        self.count = total

    def columns(self):
        """The (bins, 2) columns mean and M2, where the moments live (:func:`psd_moments_of_batch`'s form)."""
        return array_module(self._mean).stack([self._mean, self._m2], axis=1)

    @property
    def stderr(self) -> np.ndarray:
        """Standard error of the mean per bin (0 with fewer than two samples)."""
        return to_host(self.mean_and_stderr()[1])

    def mean_and_stderr(self):
        """The per-bin mean and its standard error where the moments live (NumPy or CuPy)."""
        xp = array_module(self._mean)
        if self.count < 2:
            return self._mean, xp.zeros_like(self._mean)
        return self._mean, xp.sqrt(self._m2 / (self.count - 1) / self.count)
