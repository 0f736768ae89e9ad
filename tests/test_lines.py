"""Rough lines (physics.md section 3): RMS, band, slope, lambda A, reproducibility."""

import math

import numpy as np
import pytest
from reference import psd, rough_line, to_numpy

from mdroll.errors import ParameterError
from mdroll import Params, rough_lines

P = Params(L=0.1, dx=10e-6, H=0.7)


def test_matches_independent_numpy_generator(device):
    lines = to_numpy(rough_lines(P, seed=42, realizations=[0, 5, 17], device=device))
    for row, index in zip(lines, [0, 5, 17]):
        ref = rough_line(P, 42, index)
        assert np.max(np.abs(row - ref)) <= 1e-12 * P.h0


def test_rms_is_h0_and_mean_zero(device):
    lines = to_numpy(rough_lines(P, seed=1, realizations=6, device=device))
    assert lines.shape == (6, P.n_points) and lines.dtype == np.float64
    np.testing.assert_allclose(np.sqrt(np.mean(lines**2, axis=1)), P.h0, rtol=1e-12)
    assert np.max(np.abs(lines.mean(axis=1))) < 1e-12 * P.h0


@pytest.mark.parametrize("H", [0.3, 0.7, 0.9])
def test_spectrum_band_slope_and_lambda_A(device, H):
    p = P.replace(H=H, q_max=0.5 * math.pi / P.dx)
    lines = to_numpy(rough_lines(p, seed=3, realizations=4, device=device))
    q, C = psd(lines, p.dx)
    inside = (q >= p.q_min * (1 - 1e-12)) & (q <= p.q_max * (1 + 1e-12))
    # no content outside [q_min, q_max]
    assert np.max(C[:, ~inside]) <= 1e-24 * np.max(C)
    # fixed amplitudes: every mode carries exactly lambda A q^(-2H-1) (eq 33 with eq 50)
    ratio = C[:, inside] / (p.lambda_A * q[inside] ** (-2 * H - 1))
    assert np.max(np.abs(ratio - 1)) < 1e-9
    # band-averaged log-log slope -(2H+1)
    edges = np.geomspace(p.q_min, p.q_max, 12)
    centres, means = [], []
    for lo, hi in zip(edges[:-1], edges[1:]):
        sel = (q >= lo) & (q < hi)
        centres.append(np.exp(np.mean(np.log(q[sel]))))
        means.append(np.exp(np.mean(np.log(C[:, sel].mean(axis=0)))))
    slope = np.polyfit(np.log(centres), np.log(means), 1)[0]
    assert abs(slope + (2 * H + 1)) < 0.02


def test_same_lines_whatever_the_batch_split(device):
    whole = to_numpy(rough_lines(P, seed=9, realizations=8, device=device))
    parts = [to_numpy(rough_lines(P, seed=9, realizations=idx, device=device)) for idx in ([0, 1, 2], [3], [7, 4, 5, 6])]
    split = np.concatenate(parts)[[0, 1, 2, 3, 5, 6, 7, 4]]
    assert np.max(np.abs(split - whole)) <= 1e-12 * P.h0
    other_seed = to_numpy(rough_lines(P, seed=10, realizations=1, device=device))
    assert np.max(np.abs(other_seed[0] - whole[0])) > 0.1 * P.h0


@pytest.mark.parametrize("n", [16, 15, 4096])
def test_inverse_fft_is_numpy_times_n(device, n):
    """irfft_rows is the unnormalized inverse (physics.md section 3's sum, no 1/n) on every
    device, for even and odd n; on CUDA it may overwrite the spectrum, so each call gets a copy."""
    from mdroll.devices import to_warp, warp
    from mdroll.fft import irfft_rows

    rng = np.random.default_rng(n)
    spectrum = rng.standard_normal((3, n // 2 + 1)) + 1j * rng.standard_normal((3, n // 2 + 1))
    spectrum[:, 0] = spectrum[:, 0].real  # a real line's mean and Nyquist modes are real
    if n % 2 == 0:
        spectrum[:, -1] = spectrum[:, -1].real
    pairs = np.ascontiguousarray(spectrum.view(np.float64).reshape(3, -1, 2))
    lines = to_numpy(irfft_rows(to_warp(pairs, device, dtype=warp().vec2d), n, device))
    expected = n * np.fft.irfft(spectrum, n=n, axis=-1)
    assert np.max(np.abs(lines - expected)) <= 1e-12 * np.max(np.abs(expected))


@pytest.mark.parametrize("rows", [1, 33, 70])
def test_row_transforms_are_numpys_and_each_rows_own(device, rows):
    """Both directions against NumPy for fewer and more rows than one cuFFT plan takes
    (cuda_plan_rows: whole plans, then padded rows), and each row's transform bit for bit the
    same alone as in the batch: batches of any size give a realization the same line. A plan
    holds at most 2^25 points, one row however long."""
    from mdroll.devices import to_warp, warp
    from mdroll.fft import CUDA_FFT_ROWS, cuda_plan_rows, irfft_rows, rfft_rows

    assert cuda_plan_rows(250) == cuda_plan_rows(2**20) == CUDA_FFT_ROWS == 32
    assert cuda_plan_rows(2**22) == 8 and cuda_plan_rows(2**26) == 1

    n = 250
    rng = np.random.default_rng(rows)
    x = rng.standard_normal((rows, n))
    forward = np.array(to_numpy(rfft_rows(to_warp(x, device), device)))
    assert np.max(np.abs(forward - np.fft.rfft(x, axis=-1))) <= 1e-12 * np.max(np.abs(forward))
    alone = np.array(to_numpy(rfft_rows(to_warp(x[-1:], device), device)))
    assert np.array_equal(alone[0], forward[-1])

    def inverse(spectrum):
        pairs = np.ascontiguousarray(spectrum.view(np.float64).reshape(spectrum.shape[0], -1, 2))
        return np.array(to_numpy(irfft_rows(to_warp(pairs, device, dtype=warp().vec2d), n, device)))

    lines = inverse(forward)
    assert np.max(np.abs(lines - n * x)) <= 1e-12 * n * np.max(np.abs(x))
    assert np.array_equal(inverse(forward[-1:])[0], lines[-1])


def test_cpu_and_cuda_agree(cuda_devices):
    if not cuda_devices:
        pytest.skip("no CUDA device")
    cpu = rough_lines(P, seed=5, realizations=4, device="cpu")
    for dev in cuda_devices:
        gpu = to_numpy(rough_lines(P, seed=5, realizations=4, device=dev))
        assert np.max(np.abs(gpu - cpu)) <= 1e-12 * P.h0


@pytest.mark.parametrize(
    "kwargs,name",
    [
        ({"seed": -1, "realizations": 2}, "seed"),
        ({"seed": 2**64, "realizations": 2}, "seed"),
        ({"seed": 1.5, "realizations": 2}, "seed"),
        ({"seed": 0, "realizations": 0}, "realizations"),
        ({"seed": 0, "realizations": [-1, 2]}, "realizations"),
        ({"seed": 0, "realizations": "3"}, "realizations"),
    ],
)
def test_bad_arguments(kwargs, name):
    with pytest.raises(ParameterError, match=name):
        rough_lines(P, **kwargs)
