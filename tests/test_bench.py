"""The scaling study behind ``mdroll bench`` on a tiny size: its fits, records, table and plot."""

import json
import statistics

import numpy as np
import pytest

from mdroll import ALGORITHMS, Params, bench
from mdroll.cli import main
from mdroll.forces.registry import REGISTRY


def test_fit_exponent_recovers_a_power_law():
    n = 2.0 ** np.arange(10, 16)
    rng = np.random.default_rng(0)
    t = 3e-9 * n**1.5 * np.exp(rng.normal(0, 0.02, n.size))
    slope, err = bench.fit_exponent(n, t)
    assert slope == pytest.approx(1.5, abs=4 * err) and 0 < err < 0.05


def test_device_timed_leaves_the_enqueue_outside(device):
    """On CUDA the timer reads the device's clock around the work alone: a kernel that the GPU's
    global timer holds 1 ms, enqueued after 0.1 ms of host work (within the hold before the
    start event, ``HOLD_S``), measures 1 ms, where the wall clock would read 1.1 ms or more; on
    the CPU the timer is the wall clock, which counts the host's work."""
    import time

    import warp as wp

    from mdroll.kernels.intrinsics import hold_stream

    cuda = device.startswith("cuda")

    def work():
        begin = time.perf_counter()
        while time.perf_counter() - begin < 1e-4:
            pass
        if cuda:
            wp.launch(hold_stream, dim=1, inputs=[1_000_000], device=device)

    assert bench.HOLD_S >= 2e-4  # room for the host's 0.1 ms
    wp.launch(hold_stream, dim=1, inputs=[0], device=device)  # loaded before the clock
    median, times = bench.device_timed(work, device, 5)
    assert len(times) == 5 and median == sorted(times)[2]
    if cuda:
        assert 1e-3 <= median < 1.05e-3
        # host work longer than the hold would be counted: refused, not measured
        with pytest.raises(RuntimeError, match="longer than HOLD_S"):
            bench.device_timed(lambda: time.sleep(2 * bench.HOLD_S), device, 1)
    else:
        assert median >= 1e-4


def test_force_time_names_its_clock_and_refuses_others(device):
    """force_time times on the device's clock on CUDA and the wall's on the CPU, says which in its
    record, and refuses a clock it does not have."""
    p = Params(L=0.03)
    point = bench.force_time(p, "sweep", 2, device, 2)
    assert point["clock"] == ("device events" if device.startswith("cuda") else "wall")
    assert len(point["force_times_s"]) == 2 and point["force_s"] == statistics.median(point["force_times_s"]) > 0
    assert bench.force_time(p, "sweep", 2, device, 2, clock="wall")["clock"] == "wall"
    with pytest.raises(ValueError, match="clock = 'host'"):
        bench.force_time(p, "sweep", 2, device, 2, clock="host")


def test_memory_per_realization_is_affine_in_n():
    # open boundary: steps = n - (fixed margins), so bytes = alpha n - beta
    m1, m2, m4 = (bench.memory_per_realization(Params(L=L), "tree", "cpu") for L in (0.1, 0.2, 0.4))
    assert (m4 - m2) / (m2 - m1) == pytest.approx(2.0, rel=0.02)
    # at least the line, prefix sums, force and acceleration: 4 float64 per point
    assert (m2 - m1) >= 4 * 8 * (Params(L=0.2).n_points - Params(L=0.1).n_points)
    # the sweep's CPU form builds its prefix sums with its force launch: counted like edge's,
    # whose prepared lines carry them (and the sweep's row bounds on top)
    p = Params(L=0.2)
    sweep, edge = (bench.memory_per_realization(p, algorithm, "cpu") for algorithm in ("sweep", "edge"))
    assert edge <= sweep <= edge + 64


def test_tiny_study_through_the_cli(tmp_path, monkeypatch, device):
    tiny = bench.ScalingSize(repeats=2, refinement=(0.03, (10, 11, 12), 2), distance=((13, 14, 15), 2), ensemble=(13, (1, 2)),
                           compare=(13, 2), stages=(Params(L=0.05), 2), thesis=False)
    monkeypatch.setitem(bench.SIZES, "quick", tiny)
    assert main(["bench", "--quick", "--device", device, "--out", str(tmp_path), "--no-progress"]) == 0
    record = json.loads((tmp_path / "bench.json").read_text())
    assert record["environment"][device]["device_name"]
    fits = record["fits"]["refinement"][device]
    variants = {v.name for entry in REGISTRY.values() for v in entry.bench_variants}
    assert set(fits) == set(ALGORITHMS) | variants
    # direct grows fastest under refinement: its window grows with n
    assert fits["direct"]["exponent"] > fits["edge"]["exponent"]
    assert len(record["distance"]) == 3 * len(ALGORITHMS) and all(p["force_s"] > 0 for p in record["distance"])
    assert {p["realizations"] for p in record["ensemble"]} == {1, 2}
    assert record["stages"][device]["total_s"] > 0
    assert (tmp_path / "bench.png").read_bytes()[:4] == b"\x89PNG"
