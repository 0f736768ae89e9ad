"""Ensemble pipeline (physics.md sections 5-6), its outputs and the CLI."""

import dataclasses
import json

import numpy as np
import pytest
from reference import direct_force, psd, to_numpy

from mdroll.errors import ParameterError
from mdroll import EnsembleResult, Params, contact_force, rough_lines, run_ensemble, step_range
from mdroll.forces.registry import default_algorithm
from mdroll.ensemble.pipeline import H_BOUND_SIGMAS

P = Params(L=0.05)
#: realizations of the runs of P
COUNT = 5


@pytest.mark.parametrize("window", [True, False], ids=["default-hann", "thesis-no-window"])
def test_averaged_psd_equals_mean_of_numpy_psds(device, window):
    result = run_ensemble(P, realizations=COUNT, seed=3, device=device, progress=False, batch=2, window=window)
    lines = to_numpy(rough_lines(P, 3, COUNT, device="cpu"))
    force = contact_force(lines, P, "tree", "open", h_max=H_BOUND_SIGMAS * P.h0)
    q, C = psd(force, P.dx, window=window)
    np.testing.assert_allclose(result.q, q, rtol=1e-14)
    # with the window, the pipeline's 3-bin stencil on the spectrum cancels its neighbours where the
    # reference multiplies in time: rounding relative to the neighbours, up to ~1e-8 of a small bin
    np.testing.assert_allclose(result.force_psd[1:], C.mean(axis=0)[1:], rtol=1e-7 if window else 1e-9)
    np.testing.assert_allclose(result.force_psd_stderr[1:], C.std(axis=0, ddof=1)[1:] / np.sqrt(COUNT),
                               rtol=1e-7 if window else 1e-8)
    assert result.omega == pytest.approx(q * P.v0)
    assert result.force_mean == pytest.approx(force.mean(), rel=1e-12)


@pytest.mark.parametrize("window", [False, True])
def test_decoupled_spectra_are_those_of_the_semi_implicit_euler_response(device, window):
    """The decoupled acceleration PSD, computed bin by bin from the force spectrum and the final
    state (kernels/moments.py), against the PSD of a plain sequential loop's series (section 5.1);
    the Hann window, applied as a three-bin stencil, against the window applied to the series."""
    p = Params(L=0.2)  # ~3.8e4 steps
    lines = rough_lines(p, 1, 1)
    first, steps = step_range(p, "open", p.d0, H_BOUND_SIGMAS * p.h0)
    force = contact_force(lines, p, "tree", "open", h_max=H_BOUND_SIGMAS * p.h0)[0]
    y = v = 0.0
    accel = np.empty(steps)
    for s in range(steps):
        accel[s] = (p.F_N - force[s] - p.k_contact * y) / p.m
        v += p.dt * accel[s]
        y += p.dt * v
    result = run_ensemble(p, seed=1, realizations=1, device=device, progress=False, window=window)
    for got, series in ((result.force_psd, force), (result.accel_psd, accel)):
        _, C = psd(series[None, :], p.dx, window)
        assert np.isfinite(got).all() and got.shape == C[0].shape
        np.testing.assert_allclose(got[1:], C[0, 1:], rtol=1e-9, atol=1e-12 * C[0].max())
    assert result.force_mean == pytest.approx(force.mean(), rel=1e-13)
    assert result.force_rms == pytest.approx(force.std(), rel=1e-10)


def test_coupled_windowed_spectra_are_those_of_the_coupled_series(device):
    """Coupled mode: both series through the FFT, the Hann window as a stencil, against numpy."""
    from mdroll.forces.prepare import prepare_lines
    from mdroll.ensemble.coupled import coupled_series

    p = Params(L=0.03)
    result = run_ensemble(p, realizations=2, seed=4, mode="coupled", device=device, progress=False, window=True)
    lines = rough_lines(p, 4, 2, device=device)
    prepared = prepare_lines(lines, p, "tree", "open", p.d0, device, h_max=H_BOUND_SIGMAS * p.h0)
    force, accel = (a.numpy() for a in coupled_series(prepared, p, "tree", device))
    for got, series in ((result.force_psd, force), (result.accel_psd, accel)):
        _, C = psd(series, p.dx, window=True)
        np.testing.assert_allclose(got, C.mean(axis=0), rtol=1e-9, atol=1e-12 * C.max())
    assert result.force_rms == pytest.approx(force.std(axis=1).mean(), rel=1e-10)


def test_stage_times_cover_every_stage_within_the_run(device):
    """Every stage reports a positive time (device time between CUDA events on CUDA, wall time
    on the CPU), and together they fit inside the call's wall time."""
    import time

    run_ensemble(P, realizations=COUNT, seed=2, device=device, progress=False)  # first use: compilation, plans
    t0 = time.perf_counter()
    result = run_ensemble(P, realizations=COUNT, seed=2, device=device, progress=False, batch=2)
    wall = time.perf_counter() - t0
    assert set(result.timings) == {"generate", "build", "force", "response", "spectra"}
    assert all(t > 0 for t in result.timings.values()), result.timings
    assert sum(result.timings.values()) <= wall


def test_same_result_for_any_batch_size_and_order(device):
    a = run_ensemble(P, realizations=COUNT, seed=5, device=device, progress=False, batch=1)
    b = run_ensemble(P, realizations=COUNT, seed=5, device=device, progress=False, batch=5)
    c = run_ensemble(P, seed=5, realizations=[4, 0, 3, 1, 2], device=device, progress=False, batch=2)
    # to rounding: cuFFT picks its algorithm by batch size, so bins 1e4 below the peak differ
    # by ~1e-16 of the peak (1e-12 of themselves)
    for other in (b, c):
        np.testing.assert_allclose(other.force_psd, a.force_psd, rtol=1e-12, atol=1e-14 * a.force_psd.max())
        np.testing.assert_allclose(other.accel_psd, a.accel_psd, rtol=1e-12, atol=1e-14 * a.accel_psd.max())
        np.testing.assert_allclose(other.accel_psd_stderr, a.accel_psd_stderr, rtol=1e-10,
                                   atol=1e-12 * a.accel_psd_stderr.max())


def test_coupled_smooth_line_oscillates_at_omega_0_without_energy_growth(device):
    """Semi-implicit Euler on a smooth line started 1 um off equilibrium: frequency omega_0
    (within 1 %, the linearization), no energy growth over 1e5 steps."""
    from mdroll.devices import warp
    from mdroll.forces.prepare import prepare_lines
    from mdroll.ensemble.coupled import coupled_series

    wp = warp()
    p = Params(L=0.511)  # 1e5 steps after the open margins
    flat = wp.zeros((1, p.n_points), dtype=wp.float64, device=device)
    prepared = prepare_lines(flat, p, "tree", "open", p.d0, device, 8, 0.0)
    assert prepared.steps >= 100_000
    force, accel = coupled_series(prepared, p, "tree", device, d_start=p.d0 + 1e-6)
    a = accel.numpy()[0]
    lost = int((force.numpy() <= 0).sum())
    assert lost == 0
    crossings = np.where(np.diff(np.sign(a)) != 0)[0]
    period_steps = 2 * np.mean(np.diff(crossings))
    omega = 2 * np.pi / (period_steps * p.dt)
    assert omega == pytest.approx(p.omega_0, rel=0.01)
    first_cycle = np.abs(a[: crossings[2]]).max()
    last_cycle = np.abs(a[crossings[-3]:]).max()
    # symplectic Euler keeps the amplitude to O(omega dt) = 8e-4; forward Euler would grow it by 3 %
    assert last_cycle <= first_cycle * (1 + 5e-3)


def _coupled_indentation(accel, params, d_start):
    """d(t) before each step, rebuilt from the recorded d'' with the same semi-implicit Euler step."""
    d = np.empty_like(accel)
    depth, rate = d_start, 0.0
    for s, a in enumerate(accel):
        d[s] = depth
        rate += params.dt * a
        depth += params.dt * rate
    return d


@pytest.mark.parametrize("algorithm", ["direct", "tree", "edge", "sweep"])
def test_coupled_force_is_the_force_at_the_current_indentation(device, algorithm):
    """Eq 13 step by step: every recorded F equals the numpy spring sum (eq 10-12; eq 49 for
    edge) at the wheel's position and at the indentation the recorded d'' implies. On CUDA the
    block's lanes share each step's sum, on the CPU one thread does it all."""
    from mdroll.forces.prepare import prepare_lines
    from mdroll.ensemble.coupled import coupled_series
    from mdroll.validation.references import edge_force

    p = Params(L=0.03, dx=20e-6, h0=2e-6, H=0.5)
    lines = rough_lines(p, seed=5, realizations=2, device=device)
    d_start = p.d0 * 1.02  # starts off equilibrium: d swings by ~2 um
    prepared = prepare_lines(lines, p, algorithm, "open", p.d0, device, 4)
    force, accel = coupled_series(prepared, p, algorithm, device, d_start=d_start)
    force, accel, host = force.numpy(), accel.numpy(), to_numpy(lines)
    for r in range(2):
        d = _coupled_indentation(accel[r], p, d_start)
        assert np.ptp(d) > 1e-6
        steps = np.arange(prepared.steps)
        if algorithm == "edge":
            steps = steps[:: prepared.steps // 40]
            reference = np.array([edge_force(p, host[r], d[s])[prepared.first + s] for s in steps])
        else:
            reference = direct_force(host[r], p, (prepared.first + steps) * p.dx, d[:, None])
        assert np.max(np.abs(force[r, steps] - reference)) <= 1e-11 * p.F_N


def test_coupled_and_decoupled_agree_above_resonance():
    p = Params(L=0.3)
    dec = run_ensemble(p, realizations=2, seed=2, mode="decoupled", device="cpu", progress=False)
    cou = run_ensemble(p, realizations=2, seed=2, mode="coupled", device="cpu", progress=False)
    band = (dec.omega > 2 * p.omega_0) & (dec.q < 8 * p.q_min)
    ratio = cou.accel_psd[band].mean() / dec.accel_psd[band].mean()
    assert ratio == pytest.approx(1.0, abs=0.10)
    assert cou.contact_lost_steps == 0


def test_save_load_round_trip(tmp_path):
    result = run_ensemble(P, realizations=COUNT, seed=7, device="cpu", progress=False)
    path = result.save(tmp_path / "spectra.npz")
    back = EnsembleResult.load(path)
    assert back.params == result.params and back.seed == 7 and back.algorithm == default_algorithm("decoupled")
    np.testing.assert_array_equal(back.accel_psd, result.accel_psd)
    np.testing.assert_array_equal(back.force_psd_stderr, result.force_psd_stderr)


def test_cli_quick_run_writes_readable_outputs(tmp_path, cli):
    out = tmp_path / "run"
    proc = cli("run", "--preset", "quick", "--realizations", "3", "--out", str(out), "--no-progress", "--device", "cpu")
    assert proc.returncode == 0, proc.stderr
    assert "CUDA driver" not in proc.stderr  # a CPU run says nothing about a missing GPU
    summary = json.loads((out / "summary.json").read_text())
    assert summary["n_real"] == 3 and summary["params"]["L"] == 0.2
    result = EnsembleResult.load(out / "spectra.npz")
    assert result.n_real == 3 and np.all(np.isfinite(result.accel_psd))
    for png in ("accel_psd.png", "force_psd.png"):
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_config_file_and_existing_output(tmp_path, cli):
    config = tmp_path / "c.toml"
    config.write_text("[params]\nL = 0.2\nH = 0.5\nbogus = 1\n")
    proc = cli("params", "--config", str(config))
    assert proc.returncode == 2 and "bogus" in proc.stderr
    config.write_text("[params]\nL = 0.2\nH = 0.5\n")
    proc = cli("params", "--config", str(config))
    assert proc.returncode == 0 and "0.5" in proc.stdout and "omega_0" in proc.stdout
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "x").write_text("")
    proc = cli("run", "--preset", "quick", "--out", str(tmp_path / "out"))
    assert proc.returncode == 2 and "--force" in proc.stderr


def test_series_sums_against_numpy_and_a_sequential_loop(device):
    """The read-only pass over u = F - F_N: its sums against numpy, contact lost where F <= 0,
    non-finite steps counted, and the decoupled wheel's final state (section 5.1) against a
    plain semi-implicit Euler loop from rest; zeros for the state when not decoupled."""
    from mdroll.devices import to_warp
    from mdroll.ensemble.psd import series_sums
    from mdroll.kernels.moments import FINAL_V, FINAL_Y, LOST, NOT_FINITE, SUM_DEVIATION, SUM_SQUARES

    p = Params(L=0.05)
    rng = np.random.default_rng(7)
    force = p.F_N + 50.0 * rng.standard_normal((3, 3000))
    force[1, 100:110] = 0.0  # contact lost
    force[1, 200] = -3.0  # the edge formula can go below zero
    force[2, 5] = np.nan
    u = force - p.F_N
    sums = to_numpy(series_sums(to_warp(u, device), p, device, decoupled=True))
    assert sums[:, LOST].tolist() == [0, 11, 0] and sums[:, NOT_FINITE].tolist() == [0, 0, 1]
    for r in (0, 1):
        scale = np.abs(u[r]).sum()
        assert abs(sums[r, SUM_DEVIATION] - u[r].sum()) <= 1e-14 * scale
        assert sums[r, SUM_SQUARES] == pytest.approx(np.sum(u[r] ** 2), rel=1e-13)
        y = v = 0.0
        for s in range(u.shape[1]):
            v += p.dt * (-u[r, s] - p.k_contact * y) / p.m
            y += p.dt * v
        assert sums[r, FINAL_Y] == pytest.approx(y, rel=1e-9)
        assert sums[r, FINAL_V] == pytest.approx(v, rel=1e-9)
    coupled = to_numpy(series_sums(to_warp(u, device), p, device, decoupled=False))
    assert np.all(coupled[:, FINAL_Y:] == 0.0)
    np.testing.assert_array_equal(coupled[:, :FINAL_Y], sums[:, :FINAL_Y])


def test_resumed_run_continues_on_the_device(device, tmp_path, monkeypatch):
    """A run stopped after its first batch, resumed from its checkpoint (moments saved on the
    host), equals the uninterrupted run on the same device: it goes on with the batches the
    interrupted run had planned (a checkpointed run's first batch holds one realization), so the
    moments are merged in the same groups."""
    from mdroll.ensemble import pipeline

    class Stop(Exception):
        pass

    split = pipeline._cpu_parts
    batches = []  # realizations of each batch, in order

    def recorded(idx, threads):
        batches.append(len(idx))
        return split(idx, threads)

    monkeypatch.setattr(pipeline, "_cpu_parts", recorded)
    # the uninterrupted run with a checkpoint too: its batches are then planned the same way
    full = run_ensemble(P, realizations=COUNT, seed=6, device=device, progress=False, batch=2, checkpoint=tmp_path / "full.npz")
    planned, batches[:] = list(batches), []
    original = pipeline.psd_moments_of_batch

    def stop_at_the_second_batch(*args, **kwargs):
        if len(batches) == 2:
            raise Stop
        return original(*args, **kwargs)

    checkpoint = tmp_path / "checkpoint.npz"
    monkeypatch.setattr(pipeline, "psd_moments_of_batch", stop_at_the_second_batch)
    with pytest.raises(Stop):
        run_ensemble(P, realizations=COUNT, seed=6, device=device, progress=False, batch=2, checkpoint=checkpoint)
    monkeypatch.setattr(pipeline, "psd_moments_of_batch", original)
    del batches[1:]  # the batch that was stopped
    resumed = run_ensemble(P, realizations=COUNT, seed=6, device=device, progress=False, batch=2, checkpoint=checkpoint, resume=True)
    assert planned[0] == 1 and batches == planned, (planned, batches)
    for name in ("force_psd", "force_psd_stderr", "accel_psd", "accel_psd_stderr"):
        np.testing.assert_allclose(getattr(resumed, name), getattr(full, name), rtol=1e-12)
    np.testing.assert_array_equal(resumed.q, full.q)


def test_impulse_response_is_the_euler_step_repeated(device):
    """Closed-form A^m b (Cayley-Hamilton, kernels/moments.py) against the semi-implicit Euler
    step applied m times to a unit input (section 5.1), for m up to 2e5 (a phase of ~15 rad)."""
    from mdroll.devices import warp
    from mdroll.kernels.moments import euler_impulse_response

    wp = warp()
    p = Params()
    steps = 200_001
    weights = wp.empty(steps, dtype=wp.vec2d, device=device)
    phi = 2.0 * np.arcsin(0.5 * p.omega_0 * p.dt)
    wp.launch(euler_impulse_response, dim=steps, inputs=[phi, p.dt, weights], device=device)
    weights = weights.numpy()
    w2 = p.k_contact / p.m
    y, v = p.dt**2, p.dt  # one step with u = 1 from rest
    reference = np.empty((steps, 2))
    for m in range(steps):
        reference[m] = y, v
        v += p.dt * (-w2 * y)
        y += p.dt * v
    scale = np.abs(reference).max(axis=0)
    assert np.max(np.abs(weights - reference) / scale) < 1e-9


@pytest.mark.parametrize("steps", [1215, 1296])  # odd (3^5 5) and even: the mirrored bins differ
@pytest.mark.parametrize("window", [False, True])
def test_psd_moments_equal_numpy_mean_and_variance(device, steps, window):
    """The fused spectra kernel against numpy: per-bin mean and M2 of the PSDs of given series."""
    from mdroll.devices import to_warp
    from mdroll.ensemble.psd import psd_moments_of_batch

    rng = np.random.default_rng(steps)
    force = 3.0 + rng.standard_normal((4, steps))  # a mean to remove (the pipeline removes F_N first)
    accel = rng.standard_normal((4, steps))
    got_force, got_accel, not_finite = psd_moments_of_batch(
        to_warp(force, device), to_warp(accel, device), np.zeros((4, 6)), P, device, window)
    for got, series in ((got_force, force), (got_accel, accel)):
        _, C = psd(series, P.dx, window)
        got = to_numpy(got)
        np.testing.assert_allclose(got[:, 0], C.mean(axis=0), rtol=1e-10, atol=1e-13 * C.max())
        np.testing.assert_allclose(got[:, 1], C.var(axis=0) * 4, rtol=1e-8, atol=1e-12 * C.max() ** 2)
    assert not not_finite.any()


def test_an_algorithm_is_added_by_one_registry_entry(monkeypatch):
    """A registry entry is all an algorithm needs: a copy of direct's entry under a new name,
    without a coupled step, gives direct's forces and spectra, and the coupled mode refuses it."""
    from mdroll.forces.registry import REGISTRY

    monkeypatch.setitem(REGISTRY, "direct-copy", dataclasses.replace(REGISTRY["direct"], name="direct-copy", coupled=None))
    p = Params(L=0.03)
    lines = rough_lines(p, 1, 2)
    np.testing.assert_array_equal(contact_force(lines, p, "direct-copy"), contact_force(lines, p, "direct"))
    copy = run_ensemble(p, realizations=2, seed=1, algorithm="direct-copy", device="cpu", progress=False)
    direct = run_ensemble(p, realizations=2, seed=1, algorithm="direct", device="cpu", progress=False)
    np.testing.assert_array_equal(copy.force_psd, direct.force_psd)
    with pytest.raises(ParameterError, match="'direct-copy' has no coupled step: mode = 'coupled' takes one of tree, direct, edge, sweep"):
        run_ensemble(p, realizations=2, algorithm="direct-copy", mode="coupled", progress=False)


@pytest.mark.parametrize("mode", ["decoupled", "coupled"])
def test_cpu_threads_give_the_same_spectra(mode):
    """A CPU batch split over 3 threads (parts of 2, 2, 1 realizations, moments merged in order)
    gives the one-thread run's spectra and force moments to rounding."""
    p = Params(L=0.03)
    one, three = (run_ensemble(p, realizations=5, seed=3, mode=mode, device="cpu", progress=False, batch=5, threads=t) for t in (1, 3))
    for name in ("force_psd", "accel_psd"):
        np.testing.assert_allclose(getattr(three, name), getattr(one, name), rtol=1e-12, atol=1e-14 * getattr(one, name).max())
    assert three.force_rms == pytest.approx(one.force_rms, rel=1e-12)
    assert three.force_mean == pytest.approx(one.force_mean, rel=1e-12, abs=1e-12 * p.F_N)
