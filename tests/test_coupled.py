"""The coupled kernel (eq 13) across its launch layouts and contact-point models: any count of
realizations a block, odd counts of realizations included, gives the direct sum's coupled run;
the tree's traversal path too; the modal contact point steps as a plain numpy loop of eq 13 with
the state space's zero-order-hold step."""

import numpy as np
import pytest

from mdroll import Params, rough_lines
from mdroll.ensemble.coupled import contact_compliance, coupled_series
from mdroll.forces.prepare import prepare_lines
from mdroll.statespace import ModalForm
from mdroll.track import Track
from reference import direct_force, to_numpy

#: A rough case where the wheel leaves the rail in places (50 um at 30 m/s), 5 realizations.
ROUGH = Params(L=0.05, h0=50e-6, q_min=2 * np.pi / 0.05, v0=30.0)


def _series(lines, algorithm, device, **options):
    prepared = prepare_lines(lines, ROUGH, algorithm, "open", ROUGH.d0, device, band_limit=options.pop("band_limit",
                                                                                                        2048))
    return to_numpy(coupled_series(prepared, ROUGH, algorithm, device, **options)[0])


def test_every_layout_is_the_direct_sums_coupled_run(device):
    # 5 realizations: 3 warps a block leave 1 of 6 warps idle, 4 leave 3 of 8 (CUDA; one a block on the CPU)
    lines = rough_lines(ROUGH, seed=8, realizations=5, device=device)
    direct = _series(lines, "direct", device, warps=1)
    assert np.all(np.isfinite(direct)) and (direct == 0).sum() > 20  # steps without contact
    for algorithm in ("sweep", "tree"):
        for warps in (1, 3, 4, 8):
            series = _series(lines, algorithm, device, warps=warps)
            assert np.max(np.abs(series - direct)) <= 1e-12 * ROUGH.F_N, (algorithm, warps)
    # the tree's traversal of the bands, which narrow bands never take
    assert np.max(np.abs(_series(lines, "tree", device, band_limit=0) - direct)) <= 1e-12 * ROUGH.F_N


def test_prepared_steps_are_the_direct_sums_coupled_run(device):
    # the thesis's defaults (a band of ~44 springs a side): each step's force prepared ahead over a
    # window of d, by the stepping lanes themselves (CPU), by one or three helper warps (CUDA), or
    # on CUDA without helpers the band summed directly
    p = Params(L=0.03)
    lines = rough_lines(p, seed=3, realizations=3, device=device)
    prepared = prepare_lines(lines, p, "sweep", "open", p.d0, device)
    direct = to_numpy(coupled_series(prepare_lines(lines, p, "direct", "open", p.d0, device), p, "direct", device)[0])
    assert np.ptp(direct) > 1e-3 * p.F_N
    for helpers in (None, 0, 1):
        series = to_numpy(coupled_series(prepared, p, "sweep", device, helpers=helpers)[0])
        assert np.max(np.abs(series - direct)) <= 1e-12 * p.F_N, helpers


def test_modal_contact_point_is_the_stepped_state_space(device):
    # eq 13 with d = d_w - y: y the output 2 Re sum q of q <- phi q + gamma (F - F_N), numpy in complex.
    # The fitted modes are large and cancel (|q| up to ~80 for |y| <= ~6e-8 m here), so any order of
    # their sum moves y by ~1e-13 m, F by ~3e-4 N (~7e-9 F_N, as much for the kernel with the
    # modes summed mode by mode): the tolerance is 2.5e-8 F_N
    p = Params(L=0.024, dx=20e-6, h0=2e-6, H=0.5)
    lines = rough_lines(p, seed=6, realizations=2, device=device)
    form, rigid_mass = contact_compliance(Track.preset("ballasted-soft-pad"), None)
    prepared = prepare_lines(lines, p, "sweep", "open", p.d0, device)
    force, accel = (to_numpy(a) for a in coupled_series(prepared, p, "sweep", device, compliance=(form, rigid_mass)))
    phi, gamma = form.discretize(p.dt)
    host = to_numpy(lines)
    for r in range(2):
        q = np.zeros(form.order, dtype=complex)
        y, depth, rate = 0.0, p.d0, 0.0
        for s in range(prepared.steps):
            F = direct_force(host[r], p, [(prepared.first + s) * p.dx], depth - y)[0]
            assert abs(force[r, s] - F) <= 2.5e-8 * p.F_N, (r, s)
            q = phi * q + gamma * (F - p.F_N)
            y = 2 * np.sum(q.real)
            a = (p.F_N - F) / p.m
            assert accel[r, s] == pytest.approx(a, abs=2.5e-8 * p.F_N / p.m)
            rate += p.dt * a
            depth += p.dt * rate
    assert np.ptp(force) > 0.01 * p.F_N


def test_modes_look_ahead_is_the_one_step_recursion(device):
    # the kernel steps its modes with an exact look-ahead (y from the sums of modes steps before
    # and taps on the last forces); here well-conditioned modes (a modal wheel's oscillators, the
    # wheel mass held: d = d0 - y) against the one-step recursion y = 2 Re sum q, numpy in
    # complex, over ~650 steps: the force to 1e-12 F_N, on the launch's choice of layout and
    # (CUDA) with no helpers; 35 modes, three past the held ones of a warp's 32 lanes (CUDA), 34
    # past the CPU's one lane's, stepped from the state array
    p = Params(L=0.024, dx=20e-6, h0=10e-6, H=0.5)
    frequencies = np.geomspace(140.0, 6300.0, 35)
    form = ModalForm.oscillators(frequencies, 600.0 * (140.0 / frequencies) ** 0.6,
                                 0.005 + 0.045 * (np.arange(35) % 4) / 3)
    lines = rough_lines(p, seed=2, realizations=3, device=device)
    prepared = prepare_lines(lines, p, "sweep", "open", p.d0, device)
    phi, gamma = form.discretize(p.dt)
    host = to_numpy(lines)
    reference = np.zeros((3, prepared.steps))
    for r in range(3):
        q = np.zeros(form.order, dtype=complex)
        y = 0.0
        for s in range(prepared.steps):
            F = reference[r, s] = direct_force(host[r], p, [(prepared.first + s) * p.dx], p.d0 - y)[0]
            q = phi * q + gamma * (F - p.F_N)
            y = 2 * np.sum(q.real)
    assert np.ptp(reference) > 0.05 * p.F_N
    for helpers in (None, 0):
        force = to_numpy(coupled_series(prepared, p, "sweep", device, compliance=(form, False), helpers=helpers)[0])
        assert np.max(np.abs(force - reference)) <= 1e-12 * p.F_N, helpers


def test_layout_counts_are_bounded():
    from mdroll.ensemble.coupled import coupled_helpers, coupled_layout
    from mdroll.errors import ParameterError

    assert coupled_layout(5, "cuda:0", 4) == (2, 128)
    assert coupled_layout(5, "cpu", 4) == (5, 128)
    with pytest.raises(ParameterError, match=r"^warps = 33: allowed are 1 to 32 realizations a block$"):
        coupled_layout(5, "cpu", 33)
    assert coupled_helpers(5, "cpu") == 0 and coupled_helpers(5, "cpu", 3) == 3
    with pytest.raises(ParameterError, match=r"^helpers = 32: allowed are 0 to 31 helper warps a realization$"):
        coupled_helpers(5, "cpu", 32)


def test_prepares_ahead_is_the_kernels_helped_variant():
    # the registry's flag, which sizes coupled batches, against the kernels themselves
    from mdroll.forces.registry import REGISTRY
    from mdroll.kernels.direct import coupled_direct
    from mdroll.kernels.dynamics import with_helpers
    from mdroll.kernels.edge import coupled_edge
    from mdroll.kernels.sweep_coupled import coupled_sweep
    from mdroll.kernels.tree import coupled_tree

    kernels = {"direct": coupled_direct, "edge": coupled_edge, "sweep": coupled_sweep, "tree": coupled_tree}
    assert set(kernels) == {name for name, entry in REGISTRY.items() if entry.coupled is not None}
    for name, kernel in kernels.items():
        assert REGISTRY[name].prepares_ahead == (with_helpers(kernel) is not None), name


def test_coupled_batches_are_planned_least_in_time():
    # plan_batches against the least cost over every sequence of batches that sums to the count
    # (dynamic programming), a batch of more than helped_waves waves costing direct_waves (and
    # holding at most the memory's batch), any other a time unit a wave begun; small waves
    from mdroll.ensemble.coupled import DIRECT_WAVE_TIMES, HELPED_WAVES, plan_batches

    for modal in (False, True):  # a direct launch slower than the longest helped one, else no helpers
        assert DIRECT_WAVE_TIMES[modal] > HELPED_WAVES[modal]
    for wave, batch, helped_waves, direct_waves in [(4, 14, 3, 3.3), (4, 14, 1, 2.0), (5, 12, 1, 1.5),
                                                    (4, 9, 3, 3.3), (4, 3, 3, 3.3)]:
        def cost(b):
            return direct_waves if b > helped_waves * wave else -(-b // wave)

        least = [0.0]
        for n in range(1, 61):
            least.append(min(least[n - b] + cost(b) for b in range(1, min(batch, n) + 1)))
        for count in range(61):
            sizes = plan_batches(count, batch, wave, helped_waves, direct_waves)
            assert sum(sizes) == count and all(0 < b <= batch for b in sizes), (count, sizes)
            assert sum(map(cost, sizes)) == pytest.approx(least[count]), (wave, batch, count, sizes)
    # a memory of 3.5 waves of 396: whole memory batches summed directly, the rest in helped waves
    assert plan_batches(3745, 1390, 396, 3, 3.3) == [1390, 1188, 1167]
    assert plan_batches(7490, 1390, 396, 3, 3.3) == [1390] * 4 + [1188, 742]
    assert plan_batches(1000, 1390, 396, 3, 3.3) == [1000]


def test_coupled_plan_is_the_devices(device):
    # a multiprocessor's 64 K registers hold 3 blocks of 4 warps at 168 registers a lane; the CPU
    # and an algorithm without helpers keep the memory's batch
    from mdroll.ensemble.coupled import (DIRECT_WAVE_TIMES, HELPED_WAVES, coupled_helpers, coupled_plan, helped_wave,
                                         plan_batches)

    if device == "cpu":
        assert coupled_plan(3000, 1390, "sweep", False, device) == [1390, 1390, 220]
        return
    import warp as wp

    wave = 3 * wp.get_device(device).sm_count
    assert helped_wave(device) == wave
    for modal in (False, True):
        assert coupled_plan(9 * wave, 3 * wave + 1, "sweep", modal, device) == plan_batches(
            9 * wave, 3 * wave + 1, wave, HELPED_WAVES[modal], DIRECT_WAVE_TIMES[modal])
    memory = int(3.5 * wave)
    assert coupled_plan(9 * wave, memory, "tree", False, device) == [memory] * 2 + [9 * wave - 2 * memory]
    assert coupled_helpers(3 * wave, device) == 3 and coupled_helpers(3 * wave + 1, device) == 0
    assert coupled_helpers(wave, device, modal=True) == 3 and coupled_helpers(wave + 1, device, modal=True) == 0


def test_spectra_in_parts_are_the_whole_batchs(device, monkeypatch):
    # the coupled mode's spectra go SPECTRA_ROWS rows at a time, their moments merged: 7 rows in
    # parts of 3, 3 and 1 against one part of all 7
    import warp as wp

    from mdroll.ensemble import psd

    p = Params(L=0.05)
    rng = np.random.default_rng(4)
    force, accel = (wp.array(rng.normal(size=(7, 256)), dtype=wp.float64, device=device) for _ in range(2))
    sums = psd.series_sums(force, p, device, False)

    def moments(rows):
        monkeypatch.setattr(psd, "SPECTRA_ROWS", rows)
        return [to_numpy(m).copy() for m in psd.psd_moments_of_batch(force, accel, sums, p, device, True)]

    whole, parts = moments(7), moments(3)
    assert whole[0].shape == (129, 2) and np.all(whole[0][1:, 1] > 0)
    for a, b in zip(parts, whole):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-14 * np.abs(b).max())
