"""Ensemble pipeline (physics.md sections 5-6), its outputs and the CLI."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from reference import direct_force, psd, to_numpy

from mdroll import EnsembleResult, Params, contact_force, rough_lines, run_ensemble, step_range
from mdroll.ensemble.pipeline import H_BOUND_SIGMAS

P = Params(L=0.05, n_real=5)
ROOT = Path(__file__).resolve().parents[1]


def test_averaged_psd_equals_mean_of_numpy_psds(device):
    result = run_ensemble(P, seed=3, device=device, progress=False, batch=2)
    lines = to_numpy(rough_lines(P, 3, P.n_real, device="cpu"))
    force = contact_force(lines, P, "tree", "open", h_max=H_BOUND_SIGMAS * P.h0)
    q, C = psd(force, P.dx)
    np.testing.assert_allclose(result.q, q, rtol=1e-14)
    np.testing.assert_allclose(result.force_psd[1:], C.mean(axis=0)[1:], rtol=1e-9)
    np.testing.assert_allclose(result.force_psd_stderr[1:], C.std(axis=0, ddof=1)[1:] / np.sqrt(P.n_real), rtol=1e-8)
    assert result.omega == pytest.approx(q * P.v0)
    assert result.force_mean == pytest.approx(force.mean(), rel=1e-12)


def test_decoupled_acceleration_is_the_semi_implicit_euler_response(device):
    """The chunked parallel response (RESPONSE_CHUNK steps a chunk) against a plain sequential loop."""
    p = Params(L=0.2, n_real=1)  # ~3.8e4 steps: ~150 chunks
    lines = rough_lines(p, 1, 1)
    first, steps = step_range(p, "open", p.d0, H_BOUND_SIGMAS * p.h0)
    force = contact_force(lines, p, "tree", "open", h_max=H_BOUND_SIGMAS * p.h0)[0]
    y = v = 0.0
    accel = np.empty(steps)
    for s in range(steps):
        accel[s] = (p.F_N - force[s] - p.k_contact * y) / p.m
        v += p.dt * accel[s]
        y += p.dt * v
    result = run_ensemble(p, seed=1, realizations=1, device=device, progress=False)
    q, C = psd(accel[None, :], p.dx)
    np.testing.assert_allclose(result.accel_psd[1:], C[0, 1:], rtol=1e-9)


def test_same_result_for_any_batch_size(device):
    a = run_ensemble(P, seed=5, device=device, progress=False, batch=1)
    b = run_ensemble(P, seed=5, device=device, progress=False, batch=5)
    c = run_ensemble(P, seed=5, realizations=[4, 0, 3, 1, 2], device=device, progress=False, batch=2)
    for other in (b, c):
        np.testing.assert_allclose(other.force_psd, a.force_psd, rtol=1e-12, atol=0)
        np.testing.assert_allclose(other.accel_psd, a.accel_psd, rtol=1e-12, atol=0)


def test_coupled_smooth_line_oscillates_at_omega_0_without_energy_growth(device):
    """Semi-implicit Euler on a smooth line started 1 um off equilibrium: frequency omega_0
    (within 1 %, the linearization), no energy growth over 1e5 steps."""
    from mdroll.devices import warp
    from mdroll.ensemble.force import prepare_lines
    from mdroll.ensemble.pipeline import coupled_series

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


@pytest.mark.parametrize("algorithm", ["direct", "tree", "edge"])
def test_coupled_force_is_the_force_at_the_current_indentation(device, algorithm):
    """Eq 13 step by step: every recorded F equals the numpy spring sum (eq 10-12; eq 49 for
    edge) at the wheel's position and at the indentation the recorded d'' implies. On CUDA the
    block's lanes share each step's sum, on the CPU one thread does it all."""
    from mdroll.ensemble.force import prepare_lines
    from mdroll.ensemble.pipeline import coupled_series
    from mdroll.validation.formulas import edge_force

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
    p = Params(L=0.3, n_real=2)
    dec = run_ensemble(p, seed=2, mode="decoupled", device="cpu", progress=False)
    cou = run_ensemble(p, seed=2, mode="coupled", device="cpu", progress=False)
    band = (dec.omega > 2 * p.omega_0) & (dec.q < 8 * p.q_min)
    ratio = cou.accel_psd[band].mean() / dec.accel_psd[band].mean()
    assert ratio == pytest.approx(1.0, abs=0.10)
    assert cou.contact_lost_steps == 0


def test_save_load_round_trip(tmp_path):
    result = run_ensemble(P, seed=7, device="cpu", progress=False)
    path = result.save(tmp_path / "spectra.npz")
    back = EnsembleResult.load(path)
    assert back.params == result.params and back.seed == 7 and back.algorithm == "tree"
    np.testing.assert_array_equal(back.accel_psd, result.accel_psd)
    np.testing.assert_array_equal(back.force_psd_stderr, result.force_psd_stderr)


def _cli(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "mdroll", *args], capture_output=True, text=True, cwd=cwd, timeout=300)


def test_cli_quick_run_writes_readable_outputs(tmp_path):
    out = tmp_path / "run"
    proc = _cli("run", "--preset", "quick", "--realizations", "3", "--out", str(out), "--no-progress", "--device", "cpu")
    assert proc.returncode == 0, proc.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["n_real"] == 3 and summary["params"]["L"] == 0.2
    result = EnsembleResult.load(out / "spectra.npz")
    assert result.n_real == 3 and np.all(np.isfinite(result.accel_psd))
    for png in ("accel_psd.png", "force_psd.png"):
        assert (out / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    "args,needle",
    [
        (["run", "--set", "Hurst=0.5"], "unknown parameter 'Hurst'"),
        (["run", "--set", "H=1.5"], "H = 1.5"),
        (["run", "--set", "h0=abc"], "not a number"),
        (["run", "--algorithm", "fast"], "invalid choice"),
        (["run", "--device", "cuda:7"], "does not exist"),
        (["run", "--config", "/nonexistent.toml"], "does not exist"),
        (["frobnicate"], "invalid choice"),
    ],
)
def test_cli_bad_input_exits_2_with_one_line(args, needle):
    proc = _cli(*args)
    assert proc.returncode == 2
    lines = [line for line in proc.stderr.splitlines() if "CUDA driver" not in line]
    assert len(lines) == 1 and needle in lines[0], proc.stderr
    assert "Traceback" not in proc.stderr


def test_cli_config_file_and_existing_output(tmp_path):
    config = tmp_path / "c.toml"
    config.write_text("[params]\nL = 0.2\nH = 0.5\nbogus = 1\n")
    proc = _cli("params", "--config", str(config))
    assert proc.returncode == 2 and "bogus" in proc.stderr
    config.write_text("[params]\nL = 0.2\nH = 0.5\n")
    proc = _cli("params", "--config", str(config))
    assert proc.returncode == 0 and "0.5" in proc.stdout and "omega_0" in proc.stdout
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "x").write_text("")
    proc = _cli("run", "--preset", "quick", "--out", str(tmp_path / "out"))
    assert proc.returncode == 2 and "--force" in proc.stderr


def test_euler_transfer_is_the_free_step_repeated():
    from mdroll.ensemble.pipeline import euler_transfer

    p = Params()
    y, v = 1e-6, 2e-4
    for _ in range(300):
        a = -p.k_contact * y / p.m
        v += p.dt * a
        y += p.dt * v
    np.testing.assert_allclose(euler_transfer(p, 300) @ [1e-6, 2e-4], [y, v], rtol=1e-12)
