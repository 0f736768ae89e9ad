"""Reliability (issue 6): one clear error for every bad input, never silently wrong,
deterministic ensembles, resumable runs after kill -9, bounded memory."""

import inspect
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import warp as wp

from mdroll import EnsembleResult, Params, contact_force, rough_lines, run_ensemble
from mdroll.ensemble import batching, pipeline
from mdroll.ensemble.checkpoint import CHECKPOINT, read_checkpoint
from mdroll.ensemble.pipeline import NonFiniteError

ROOT = Path(__file__).resolve().parents[1]
P = Params(L=0.05, n_real=6)


@wp.kernel
def _float32_kernel(x: wp.array(dtype=wp.float32), scale: wp.float32):
    """A negative control for the dtype guard below."""
    x[wp.tid()] = scale


# ----------------------------------------------------------------------------- bad input, API
LINES = np.zeros((1, P.n_points))
API_CASES = [
    (lambda: Params(H=float("nan")), "H"),
    (lambda: Params(dx="5e-6"), "dx"),
    (lambda: Params(n_real=0), "n_real"),
    (lambda: rough_lines(P, -1, 2), "seed"),
    (lambda: rough_lines(P, 0, 0), "realizations"),
    (lambda: rough_lines(P, 0, [1.5]), "realizations"),
    (lambda: contact_force(LINES, P, algorithm="fast"), "algorithm"),
    (lambda: contact_force(LINES, P, boundary="wrap"), "boundary"),
    (lambda: contact_force(LINES, P, d=-1e-6), "d = "),
    (lambda: contact_force(LINES, P, d=float("nan")), "d = nan"),
    (lambda: contact_force(LINES, P, leaf_size=0), "leaf_size = 0 .* positive integer"),
    (lambda: contact_force(LINES, P, band_limit=-1), "band_limit = -1 .* >= 0"),
    (lambda: contact_force(LINES, P, h_max=float("inf")), "h_max = inf"),
    (lambda: contact_force(LINES, "params"), "params must be an mdroll.Params"),
    (lambda: contact_force(LINES.astype(np.float32), P), "float64"),
    (lambda: contact_force(np.zeros((1, 10)), P), "shape"),
    (lambda: contact_force(np.zeros((2, 100)), P), "shape"),
    (lambda: contact_force(LINES, P, device="cuda:9"), "cuda:9"),
    (lambda: run_ensemble(P, realizations=0, progress=False), "realizations"),
    (lambda: run_ensemble(P, mode="implicit", progress=False), "mode"),
    (lambda: run_ensemble(P, algorithm="fast", progress=False), "algorithm = 'fast' .* choose one of tree, direct, edge"),
    (lambda: run_ensemble(P, batch=0, progress=False), "batch"),
    (lambda: run_ensemble(P, batch=2.5, progress=False), "batch = 2.5 .* positive integer"),
    (lambda: run_ensemble(P, memory_limit=-5, progress=False), "memory_limit"),
    (lambda: run_ensemble(P, memory_limit=1.5e9, progress=False), "memory_limit = 1500000000.0 .* positive integer"),
    (lambda: run_ensemble(P, leaf_size=0, progress=False), "leaf_size = 0 .* positive integer"),
    (lambda: run_ensemble(P, leaf_size=True, progress=False), "leaf_size = True"),
    (lambda: run_ensemble(P, window="yes", progress=False), "window = 'yes' .* True or False"),
    (lambda: run_ensemble(P, progress=None), "progress = None"),
    (lambda: run_ensemble(None, progress=False), "params must be an mdroll.Params"),
    (lambda: run_ensemble(P, device="tpu", progress=False), "tpu"),
]


@pytest.mark.parametrize("call,needle", API_CASES, ids=[f"{i}-{c[1]}" for i, c in enumerate(API_CASES)])
def test_api_rejects_bad_input_naming_it(call, needle):
    with pytest.raises(ValueError, match=needle):
        call()


# ----------------------------------------------------------------------------- bad input, CLI
CLI_CASES = [
    (["run", "--set", "n_real=abc"], "not a number"),
    (["run", "--realizations", "0", "--device", "cpu"], "--realizations 0"),
    (["run", "--first", "-3", "--device", "cpu"], "--first"),
    (["run", "--memory-limit", "0", "--device", "cpu"], "--memory-limit"),
    (["run", "--set", "nu=0.7"], "nu = 0.7"),
    (["run", "--resume", "/nonexistent-run"], "no checkpoint.npz"),
    (["run", "--device", "gpu"], "gpu"),
    (["merge", "/nonexistent-run"], "no spectra.npz"),
    (["validate", "--quick", "--full"], "not allowed"),
    (["run", "--set", "Hurst=0.5"], "unknown parameter 'Hurst'"),
    (["run", "--set", "H=1.5"], "H = 1.5"),
    (["run", "--set", "h0=abc"], "not a number"),
    (["run", "--algorithm", "fast"], "invalid choice"),
    (["run", "--device", "cuda:7"], "does not exist"),
    (["run", "--config", "/nonexistent.toml"], "does not exist"),
    (["frobnicate"], "invalid choice"),
]


@pytest.mark.parametrize("args,needle", CLI_CASES, ids=[" ".join(c[0]) for c in CLI_CASES])
def test_cli_rejects_bad_input_in_one_line(args, needle, cli, one_line_error):
    one_line_error(cli(*args), needle)


@pytest.mark.parametrize("text,needle", [
    ("[params]\nH = 0.5\nL = = 2\n", "line 3"),
    ("H = \"abc\"\n", "H"),
    ("[params]\nHurst = 0.5\n", "valid ones are"),
])
def test_cli_rejects_bad_config_files(tmp_path, text, needle, cli, one_line_error):
    config = tmp_path / "bad.toml"
    config.write_text(text)
    one_line_error(cli("params", "--config", str(config)), needle)


# ----------------------------------------------------------------------------- never silently wrong
def test_non_finite_force_stops_the_run_naming_realization_and_stage(monkeypatch):
    real = pipeline.rough_lines

    def poisoned(params, seed, idx, device):
        lines = np.array(real(params, seed, idx, device=device))
        if 4 in idx:
            lines[list(idx).index(4), 100] = np.nan
        return lines

    monkeypatch.setattr(pipeline, "rough_lines", poisoned)
    with pytest.raises(NonFiniteError, match="realization 4 at stage 'force'"):
        run_ensemble(P, realizations=range(2, 6), device="cpu", batch=2, progress=False)


def test_contact_loss_is_counted_in_both_modes():
    # 50 um roughness with waves up to 5 cm at 30 m/s: the wheel leaves the rail in places
    rough = Params(L=0.2, h0=50e-6, q_min=2 * np.pi / 0.05, v0=30.0)
    dec = run_ensemble(rough, realizations=2, device="cpu", progress=False, boundary="periodic")
    cou = run_ensemble(rough, realizations=2, device="cpu", progress=False, mode="coupled")
    for result in (dec, cou):
        assert result.contact_lost_steps > 0
    smooth = run_ensemble(P, realizations=2, device="cpu", progress=False)
    assert smooth.contact_lost_steps == 0


def test_tree_stack_bound_is_checked_before_launch(monkeypatch):
    """The launch checks the length of the stack the kernels are compiled with (one source)."""
    import mdroll.kernels.common as common
    from mdroll.ensemble.prepare import tree_levels

    lines = rough_lines(P, 0, 1)
    levels = len(tree_levels(P.n_points, 1))
    # one short of 2 + top level (never compiled: the check comes before any launch)
    monkeypatch.setattr(common, "tree_stack", wp.types.vector(length=levels, dtype=wp.int32))
    with pytest.raises(ValueError, match="leaf_size = 1"):
        contact_force(lines, P, "tree", leaf_size=1)


def float32_arguments(module) -> tuple[list[str], int]:
    """``module.kernel(arg)`` for each float32/float16 (or bare Python float) argument of the
    Warp kernels and funcs defined in ``module``, and how many kernels and funcs were read."""
    import warp as wp

    bad, checked = [], 0
    for name, obj in vars(module).items():
        if isinstance(obj, (wp.Kernel, wp.Function)) and obj.__module__ == module.__name__:
            for arg, parameter in inspect.signature(obj.func).parameters.items():
                kind = parameter.annotation
                scalar = getattr(getattr(kind, "dtype", kind), "_wp_scalar_type_", getattr(kind, "dtype", kind))
                if scalar in (wp.float32, wp.float16) or kind is float:
                    bad.append(f"{name}({arg})")
            checked += 1
    return bad, checked


def test_every_kernel_argument_on_the_force_path_is_float64():
    from mdroll.kernels import common, direct, dynamics, edge, lines, tree

    total = 0
    for module in (common, direct, dynamics, edge, lines, tree):
        bad, checked = float32_arguments(module)
        assert not bad, f"{module.__name__}: {bad}"
        total += checked
    assert total >= 20
    # the check itself catches a float32 kernel (defined below, never launched)
    assert float32_arguments(sys.modules[__name__]) == (["_float32_kernel(x)", "_float32_kernel(scale)"], 1)


# ----------------------------------------------------------------------------- deterministic
def test_cpu_and_cuda_give_the_same_spectra(cuda_devices):
    if not cuda_devices:
        pytest.skip("no CUDA device")
    cpu = run_ensemble(P, seed=3, device="cpu", progress=False)
    for device in cuda_devices:
        gpu = run_ensemble(P, seed=3, device=device, progress=False)
        np.testing.assert_allclose(gpu.force_psd, cpu.force_psd, rtol=1e-9, atol=1e-12 * cpu.force_psd.max())
        np.testing.assert_allclose(gpu.accel_psd, cpu.accel_psd, rtol=1e-9, atol=1e-12 * cpu.accel_psd.max())


def test_split_across_processes_and_merged(tmp_path, cli):
    common = ["--set", "L=0.05", "--device", "cpu", "--no-progress", "--seed", "4"]
    procs = [subprocess.Popen([sys.executable, "-m", "mdroll", "run", "--realizations", "3", "--first", str(first),
                               "--out", str(tmp_path / f"part{first}"), *common], cwd=ROOT,
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE) for first in (0, 3)]
    assert all(p.wait(timeout=300) == 0 for p in procs)
    assert cli("merge", str(tmp_path / "part0"), str(tmp_path / "part3"), "--out", str(tmp_path / "merged"),
                "--no-progress").returncode == 0
    merged = EnsembleResult.load(tmp_path / "merged" / "spectra.npz")
    whole = run_ensemble(P, seed=4, device="cpu", progress=False)
    assert merged.n_real == 6 and sorted(merged.realizations) == list(range(6))
    np.testing.assert_allclose(merged.accel_psd, whole.accel_psd, rtol=1e-12, atol=1e-12 * whole.accel_psd.max())
    np.testing.assert_allclose(merged.force_psd_stderr, whole.force_psd_stderr, rtol=1e-10)
    assert merged.force_rms == pytest.approx(whole.force_rms, rel=1e-12)
    with pytest.raises(ValueError, match="share realizations"):
        EnsembleResult.merge([whole, whole])


# ----------------------------------------------------------------------------- resumable
def test_kill_9_then_resume_equals_an_uninterrupted_run(tmp_path, cli, one_line_error):
    out = tmp_path / "run"
    args = ["run", "--set", "L=0.05", "--realizations", "400", "--batch", "2", "--device", "cpu", "--no-progress",
            "--seed", "11"]
    proc = subprocess.Popen([sys.executable, "-m", "mdroll", *args, "--out", str(out)], cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    checkpoint = out / CHECKPOINT
    deadline = time.time() + 240
    while time.time() < deadline and proc.poll() is None:
        if checkpoint.exists() and read_checkpoint(checkpoint)[0]["done"] >= 20:
            break
        time.sleep(0.01)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    done = read_checkpoint(checkpoint)[0]["done"]
    assert 0 < done < 400, "the run must have been killed part way"
    assert not (out / "spectra.npz").exists()

    refused = cli("run", "--resume", str(out), "--set", "H=0.5", "--no-progress")
    one_line_error(refused, "H: 0.7 (checkpoint) vs 0.5 (now)")

    resumed = cli("run", "--resume", str(out), "--no-progress", "--device", "cpu")
    assert resumed.returncode == 0, resumed.stderr
    result = EnsembleResult.load(out / "spectra.npz")
    whole = run_ensemble(Params(L=0.05), seed=11, realizations=400, device="cpu", batch=50, progress=False)
    assert result.n_real == 400
    np.testing.assert_allclose(result.force_psd, whole.force_psd, rtol=1e-12, atol=1e-12 * whole.force_psd.max())
    np.testing.assert_allclose(result.accel_psd, whole.accel_psd, rtol=1e-12, atol=1e-12 * whole.accel_psd.max())
    np.testing.assert_allclose(result.accel_psd_stderr, whole.accel_psd_stderr, rtol=1e-9)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["n_real"] == 400


# ----------------------------------------------------------------------------- bounded memory
def test_memory_cap_shrinks_batches_and_the_run_completes():
    per_realization = batching.BYTES_PER_POINT * P.n_points
    capped = run_ensemble(P, seed=2, device="cpu", progress=False, memory_limit=4 * per_realization)
    assert capped.batch == 2  # half the cap: two realizations a batch, three batches
    free = run_ensemble(P, seed=2, device="cpu", progress=False)
    assert free.batch >= 6
    np.testing.assert_allclose(capped.force_psd, free.force_psd, rtol=1e-12, atol=1e-12 * free.force_psd.max())


def test_thesis_scale_batches_fit_a_24_gib_host():
    thesis = Params()
    batch = batching.default_batch(thesis, "cpu", memory_limit=24 * 2**30)
    assert 1 <= batch < thesis.n_real
    assert batch * batching.BYTES_PER_POINT * thesis.n_points <= 12 * 2**30
