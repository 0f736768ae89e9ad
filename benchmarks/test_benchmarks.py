"""Timings per algorithm and device: rough-line generation, tree build, force, coupled dynamics,
spectra and end-to-end ensembles, for n = 2^log2n points per line (dx = 5 um, periodic
boundary so that every size from 2^12 has steps). Groups put the algorithms of one size and
device in one table. Each round gets fresh lines (a new seed) outside the clock, and the device
is synchronized inside the timed call."""

import pytest

from mdroll import ALGORITHMS, Params, rough_lines, run_ensemble
from mdroll.devices import synchronize, to_warp
from mdroll.forces.force import launch_force
from mdroll.forces.prepare import prepare_lines
from mdroll.forces.registry import REGISTRY
from mdroll.ensemble.coupled import coupled_series
from mdroll.ensemble.psd import psd_moments_of_batch, series_sums

#: realizations per benchmark and the largest CPU problem (points x realizations) per kind
REALIZATIONS = {"cpu": 4, "cuda": 64}
CPU_LIMIT = {"direct": 2**18, "coupled-direct": 2**16, "default": 2**22}


def _setup(device, log2n, algorithm=None, kind=None):
    dev = "cuda" if device.startswith("cuda") else "cpu"
    count = REALIZATIONS[dev]
    limit = CPU_LIMIT.get(kind or algorithm, CPU_LIMIT["default"])
    if dev == "cpu" and 2**log2n * count > limit * REALIZATIONS["cpu"]:
        pytest.skip(f"{kind or algorithm} at 2^{log2n} is too slow on one CPU core")
    return Params(L=2**log2n * 5e-6), count


def _rounds(benchmark, device, fn, setup):
    def target(*args):
        out = fn(*args)
        synchronize(device)
        return out

    seeds = iter(range(1, 10**6))
    return benchmark.pedantic(target, setup=lambda: ((setup(next(seeds)),), {}), rounds=3, iterations=1, warmup_rounds=1)


def _lines(params, seed, count, device):
    return to_warp(rough_lines(params, seed, count, device=device), device)


def test_generate(benchmark, device, log2n):
    params, count = _setup(device, log2n)
    benchmark.group = f"generate {device}"
    lines = _rounds(benchmark, device, lambda seed: _lines(params, seed, count, device), lambda seed: seed)
    assert lines.shape == (count, params.n_points)


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_build(benchmark, device, log2n, algorithm):
    params, count = _setup(device, log2n, algorithm)
    benchmark.group = f"build {device} n=2^{log2n}"
    prepared = _rounds(benchmark, device, lambda lines: prepare_lines(lines, params, algorithm, "periodic", params.d0, device),
                       lambda seed: _lines(params, seed, count, device))
    assert prepared.steps == params.n_points


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_force(benchmark, device, log2n, algorithm):
    params, count = _setup(device, log2n, algorithm)
    benchmark.group = f"force {device} n=2^{log2n}"
    force = _rounds(benchmark, device, lambda prepared: launch_force(prepared, params, algorithm, params.d0, device),
                    lambda seed: prepare_lines(_lines(params, seed, count, device), params, algorithm, "periodic",
                                               params.d0, device))
    assert force.shape == (count, params.n_points)


@pytest.mark.parametrize("algorithm", [name for name in ALGORITHMS if REGISTRY[name].coupled is not None])
def test_coupled_dynamics(benchmark, device, log2n, algorithm):
    params, count = _setup(device, log2n, algorithm, kind=f"coupled-{algorithm}")
    benchmark.group = f"coupled {device} n=2^{log2n}"
    force, accel = _rounds(benchmark, device, lambda prepared: coupled_series(prepared, params, algorithm, device),
                                 lambda seed: prepare_lines(_lines(params, seed, count, device), params, algorithm,
                                                            "periodic", params.d0, device))
    assert (force.numpy() > 0).all() and accel.shape == force.shape  # contact never lost


def test_spectra(benchmark, device, log2n):
    """The spectra stage of the pipeline on lines standing in for force series: one pass for the
    sums and the decoupled final state, the real FFT, the fused PSD moments."""
    params, count = _setup(device, log2n)
    benchmark.group = f"spectra {device}"

    def spectra(series):
        sums = series_sums(series, params, device, decoupled=True)
        return psd_moments_of_batch(series, None, sums, params, device)

    force_moments, _, _ = _rounds(benchmark, device, spectra, lambda seed: _lines(params, seed, count, device))
    assert force_moments.shape == (params.n_points // 2 + 1, 2)


@pytest.mark.parametrize("algorithm", ALGORITHMS)
def test_end_to_end(benchmark, device, log2n, algorithm):
    params, count = _setup(device, log2n, algorithm)
    benchmark.group = f"end to end {device} n=2^{log2n}"
    result = _rounds(benchmark, device,
                     lambda seed: run_ensemble(params, seed=seed, realizations=count, algorithm=algorithm,
                                               boundary="periodic", device=device, progress=False),
                     lambda seed: seed)
    assert result.n_real == count
