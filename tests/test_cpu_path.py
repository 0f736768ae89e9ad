"""The CPU path of the pipeline: parts taken by threads into kept buffers, FFTW plans
kept per thread, and the plots' column extremes."""

import numpy as np
import pytest

from mdroll import Params, run_ensemble
from mdroll.devices import warp
from mdroll import buffers
from mdroll.ensemble import pipeline
from mdroll.fft import fftw_threads, irfft_rows, rfft_rows
from mdroll.plotting import column_extremes

P = Params(L=0.03)
#: realizations of the runs of P
COUNT = 7


def test_the_spectra_do_not_depend_on_the_threads():
    """Parts merged in their order whichever thread ran them: 1, 2 or 3 threads give the same
    bits (7 realizations: parts of 2, 2, 2, 1)."""
    runs = [run_ensemble(P, realizations=COUNT, seed=5, device="cpu", progress=False, threads=t) for t in (1, 2, 3)]
    for run in runs[1:]:
        for name in ("force_psd", "force_psd_stderr", "accel_psd", "accel_psd_stderr"):
            np.testing.assert_array_equal(getattr(run, name), getattr(runs[0], name))
        assert (run.force_mean, run.force_rms) == (runs[0].force_mean, runs[0].force_rms)


def test_a_thread_allocates_its_buffers_once(monkeypatch):
    """One thread: a run of four parts (the last shorter) makes as many arrays as a run of one
    part, each of a whole part's rows: every stage reuses its buffer from part to part."""
    made = []
    original = buffers._host_array

    def recorded(shape, dtype):
        made.append(shape)
        return original(shape, dtype)

    monkeypatch.setattr(buffers, "_host_array", recorded)
    run_ensemble(P, seed=5, device="cpu", progress=False, threads=1, realizations=pipeline.CPU_CHUNK)
    one_part, made[:] = list(made), []
    run_ensemble(P, realizations=COUNT, seed=5, device="cpu", progress=False, threads=1)
    assert len(one_part) >= 4 and made == one_part, (one_part, made)
    assert all(shape[0] == pipeline.CPU_CHUNK for shape in made if len(shape) == 2)


def test_buffers_keep_their_memory_and_align_rows():
    wp = warp()
    kept = buffers.Buffers()
    with buffers.reused(kept):
        first = buffers.empty("a", (3, 10), wp.vec2d, "cpu", aligned=True)
        again = buffers.empty("a", (2, 10), wp.vec2d, "cpu", aligned=True)
        larger = buffers.empty("a", (4, 10), wp.vec2d, "cpu", aligned=True)
        flat = buffers.empty("b", (7,), wp.float64, "cpu")
    outside = buffers.empty("a", (3, 10), wp.vec2d, "cpu")
    assert first.shape == (3, 10) and again.shape == (2, 10) and larger.shape == (4, 10) and flat.shape == (7,)
    assert again.ptr == first.ptr and larger.ptr != first.ptr and outside.ptr not in (first.ptr, larger.ptr)
    # rows of 10 x 16 bytes padded to 192: each starts on a 64-byte boundary
    assert first.strides == (192, 16) and all(row.ctypes.data % 64 == 0 for row in first.numpy())


@pytest.mark.parametrize("n", [1000, 1001])
def test_kept_plans_transform_like_numpy_on_any_rows(n):
    """irfft_rows (unnormalized) and rfft_rows against NumPy, on rows aligned or not (a view one
    element in), within a thread's buffers or not: the same values to rounding wherever the rows
    lie (FFTW's codelets for the two layouts may differ by rounding on some CPUs, up to a
    relative ~1e-12 in a row)."""
    rng = np.random.default_rng(n)
    half = rng.standard_normal((3, n // 2 + 2)) + 1j * rng.standard_normal((3, n // 2 + 2))
    half[:, 1] = half[:, 1].real  # the zero mode of the shifted view is real
    if n % 2 == 0:
        half[:, -1] = half[:, -1].real
    lines = irfft_rows(half[:, 1:], n, "cpu")
    np.testing.assert_allclose(lines, n * np.fft.irfft(half[:, 1:], n), rtol=0, atol=1e-12 * np.abs(lines).max())
    with fftw_threads(1), buffers.reused(buffers.Buffers()):
        np.testing.assert_allclose(irfft_rows(np.ascontiguousarray(half[:, 1:]), n, "cpu"), lines, rtol=0,
                                   atol=1e-12 * np.abs(lines).max())
        shifted = np.empty((3, n + 1))
        shifted[:, 1:] = lines
        transform = rfft_rows(shifted[:, 1:], "cpu")
        np.testing.assert_allclose(rfft_rows(lines, "cpu"), transform, rtol=0, atol=1e-12 * np.abs(transform).max())
    np.testing.assert_allclose(transform, np.fft.rfft(lines), rtol=0, atol=1e-12 * np.abs(transform).max())


def test_column_extremes_keep_each_columns_range():
    """Per log-x column, the kept points span the same range as all points of each series, and
    the ends of every column are kept (a plot through them matches the full one pixel for pixel)."""
    rng = np.random.default_rng(1)
    x = np.arange(1, 200_001, dtype=float)
    series = (rng.standard_normal(x.size), np.where((rng.random(x.size) < 0.1) & (x > 1000), np.nan, 1 / x))
    kept = column_extremes(x, series, columns=100)
    column = np.minimum((np.log(x) / np.log(x[-1]) * 100).astype(int), 99)
    assert kept.size < 1000 and np.all(np.diff(kept) > 0)
    for c in np.unique(column):
        every, chosen = np.flatnonzero(column == c), kept[column[kept] == c]
        assert chosen[0] == every[0] and chosen[-1] == every[-1]
        for values in series:
            assert np.nanmin(values[chosen]) == np.nanmin(values[every])
            assert np.nanmax(values[chosen]) == np.nanmax(values[every])


@pytest.mark.parametrize("bins", [4097, 10_000])
def test_the_cpu_spans_make_the_same_modes(bins):
    """random_phase_spans (the CPU's, 4096 modes a thread) equals random_phase_spectrum (two modes
    a thread) to the bit, Nyquist mode included."""
    from mdroll.kernels.lines import random_phase_spans, random_phase_spectrum

    wp = warp()
    rng = np.random.default_rng(bins)
    keys = wp.array(rng.integers(0, 2**63, 3, dtype=np.uint64), dtype=wp.uint64, device="cpu")
    amplitudes = wp.array(np.where(rng.random(bins) < 0.2, 0.0, rng.random(bins)), dtype=wp.float64, device="cpu")
    scales = wp.array(rng.random(3), dtype=wp.float64, device="cpu")
    pairs, spans = (wp.empty((3, bins), dtype=wp.vec2d, device="cpu") for _ in range(2))
    wp.launch(random_phase_spectrum, dim=(3, (bins + 1) // 2), inputs=[keys, amplitudes, bins - 1, scales, pairs],
              device="cpu")
    wp.launch(random_phase_spans, dim=(3, -(-bins // 4096)), inputs=[keys, amplitudes, bins - 1, scales, 4096, spans],
              device="cpu")
    assert np.abs(pairs.numpy()).max() > 0 and (pairs.numpy()[:, -1, 1] == 0).all()
    np.testing.assert_array_equal(spans.numpy(), pairs.numpy())
