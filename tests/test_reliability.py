"""Reliability: one clear error for every bad input, never silently wrong,
deterministic ensembles, resumable runs after kill -9, bounded memory."""

import errno
import inspect
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import warp as wp

from mdroll import EnsembleResult, Params, __version__ as mdroll_version, contact_force, rough_lines, run_ensemble
from mdroll.cli import main as cli_main
from mdroll.cli.common import LOCK
from mdroll.cli.run import RUN_OUTPUTS
from mdroll.ensemble.resolution import Resolution
from mdroll.ensemble import batching, checkpoint as checkpoint_module, pipeline, validity
from mdroll.forces.indenter import reach
from mdroll.ensemble.checkpoint import CHECKPOINT, read_checkpoint
from mdroll.ensemble.realizations import DEFAULT_REALIZATIONS, read_params
from mdroll.errors import NonFiniteError

ROOT = Path(__file__).resolve().parents[1]
P = Params(L=0.05)
#: realizations of the runs of P
COUNT = 6


@wp.kernel
def _float32_kernel(x: wp.array(dtype=wp.float32), scale: wp.float32):
    """A negative control for the dtype guard below."""
    x[wp.tid()] = scale


# ----------------------------------------------------------------------------- bad input, API
LINES = np.zeros((1, P.n_points))
API_CASES = [
    (lambda: Params(H=float("nan")), "H"),
    (lambda: Params(dx="5e-6"), "dx"),
    (lambda: read_params({"n_real": 0}), "n_real = 0 is not allowed: it must be a positive integer"),
    (lambda: Params().replace(n_real=8), r"unknown parameter\(s\) \['n_real'\]"),  # the count is the run's
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
    (lambda: run_ensemble(P, realizations=COUNT, mode="implicit", progress=False), "mode"),
    (lambda: run_ensemble(P, realizations=COUNT, algorithm="fast", progress=False), "algorithm = 'fast' .* choose one of tree, direct, edge"),
    (lambda: run_ensemble(P, realizations=COUNT, batch=0, progress=False), "batch"),
    (lambda: run_ensemble(P, realizations=COUNT, batch=2.5, progress=False), "batch = 2.5 .* positive integer"),
    (lambda: run_ensemble(P, realizations=COUNT, memory_limit=-5, progress=False), "memory_limit"),
    (lambda: run_ensemble(P, realizations=COUNT, memory_limit=1.5e9, progress=False), "memory_limit = 1500000000.0 .* positive integer"),
    (lambda: run_ensemble(P, realizations=COUNT, leaf_size=0, progress=False), "leaf_size = 0 .* positive integer"),
    (lambda: run_ensemble(P, realizations=COUNT, leaf_size=True, progress=False), "leaf_size = True"),
    (lambda: run_ensemble(P, realizations=COUNT, window="yes", progress=False), "window = 'yes' .* True or False"),
    (lambda: run_ensemble(P, realizations=COUNT, progress=None), "progress = None"),
    (lambda: run_ensemble(None, progress=False), "params must be an mdroll.Params"),
    (lambda: run_ensemble(P, realizations=COUNT, device="tpu", progress=False), "tpu"),
]


@pytest.mark.parametrize("call,needle", API_CASES, ids=[f"{i}-{c[1]}" for i, c in enumerate(API_CASES)])
def test_api_rejects_bad_input_naming_it(call, needle):
    with pytest.raises(ValueError, match=needle):
        call()


# ----------------------------------------------------------------------------- bad input, CLI
CLI_CASES = [
    (["run", "--set", "n_real=abc"], "not an integer"),
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

    def poisoned(params, seed, idx, device, **options):
        lines = np.array(real(params, seed, idx, device=device, **options))
        if 4 in idx:
            lines[list(idx).index(4), 100] = np.nan
        return lines

    monkeypatch.setattr(pipeline, "rough_lines", poisoned)
    with pytest.raises(NonFiniteError, match="realization 4 at stage 'force'"):
        run_ensemble(P, realizations=range(2, 6), device="cpu", batch=2, progress=False)


def test_a_failed_batch_ends_the_run_after_the_next_was_queued_and_before_with_a_checkpoint(
        monkeypatch, device, tmp_path):
    """Without a checkpoint the host queues batch k + 1 before it checks batch k; the failed
    check still ends the run, naming the realization. With one, no batch begins before the last
    ended."""
    real = pipeline.rough_lines
    made = []

    def poisoned(params, seed, idx, device, **options):
        made.append(list(idx))
        lines = real(params, seed, idx, device=device, **options)
        lines = np.array(lines.numpy() if hasattr(lines, "numpy") else lines)
        if 0 in idx:
            lines[list(idx).index(0), 100] = np.nan
        return lines

    monkeypatch.setattr(pipeline, "rough_lines", poisoned)
    with pytest.raises(NonFiniteError, match="realization 0 at stage 'force'"):
        run_ensemble(P, realizations=6, device=device, batch=2, progress=False)
    assert made == [[0, 1], [2, 3]]
    made.clear()
    with pytest.raises(NonFiniteError, match="realization 0 at stage 'force'"):
        run_ensemble(P, realizations=6, device=device, batch=2, progress=False, checkpoint=tmp_path / "c.npz")
    assert made == [[0]]  # a checkpointed run's first batch holds one realization


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
    from mdroll.forces.prepared import tree_levels

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
    cpu = run_ensemble(P, realizations=COUNT, seed=3, device="cpu", progress=False)
    for device in cuda_devices:
        gpu = run_ensemble(P, realizations=COUNT, seed=3, device=device, progress=False)
        np.testing.assert_allclose(gpu.force_psd, cpu.force_psd, rtol=1e-9, atol=1e-12 * cpu.force_psd.max())
        np.testing.assert_allclose(gpu.accel_psd, cpu.accel_psd, rtol=1e-9, atol=1e-12 * cpu.accel_psd.max())


def test_split_across_processes_and_merged(quick_plots, tmp_path, capsys):
    """Unequal parts started together without --out: each keeps its own locked directory (none
    shares another's), and the merge is the whole ensemble."""
    common = ["--set", "L=0.05", "--device", "cpu", "--no-progress", "--seed", "4"]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    procs = [subprocess.Popen([sys.executable, "-m", "mdroll", "run", "--first", str(first), "--realizations", str(count),
                               *common], cwd=tmp_path, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
             for first, count in ((0, 4), (4, 2))]
    assert all(p.wait(timeout=300) == 0 for p in procs), [p.stderr.read() for p in procs]
    parts = sorted((tmp_path / "mdroll-out").iterdir())
    assert len(parts) == 2
    merged_dir = tmp_path / "merged"
    assert _main(capsys, "merge", *parts, "--out", merged_dir, "--no-progress")[0] == 0
    merged = EnsembleResult.load(merged_dir / "spectra.npz")
    whole = run_ensemble(P, realizations=COUNT, seed=4, device="cpu", progress=False)
    assert merged.n_real == 6 and "n_real" not in merged.params.as_dict() and sorted(merged.realizations) == list(range(6))
    assert merged.params == whole.params and json.loads((merged_dir / "summary.json").read_text())["n_real"] == 6
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

    resumed = cli("run", "--resume", str(out), "--no-progress", "--device", "cpu", "--batch", "50")  # not its 2
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
    capped = run_ensemble(P, realizations=COUNT, seed=2, device="cpu", progress=False, memory_limit=4 * per_realization)
    assert capped.batch == 2  # half the cap: two realizations a batch, three batches
    free = run_ensemble(P, realizations=COUNT, seed=2, device="cpu", progress=False)
    assert free.batch >= 6
    np.testing.assert_allclose(capped.force_psd, free.force_psd, rtol=1e-12, atol=1e-12 * free.force_psd.max())


def test_thesis_scale_batches_fit_a_24_gib_host():
    thesis = Params()
    batch = batching.default_batch(thesis, "cpu", memory_limit=24 * 2**30)
    assert 1 <= batch < DEFAULT_REALIZATIONS
    assert batch * batching.BYTES_PER_POINT * thesis.n_points <= 12 * 2**30


def test_repeated_runs_reuse_the_pools_memory(monkeypatch):
    # default_batch on a simulated CUDA device of 100 realizations' memory: a run that the free
    # memory would split makes the pools hand theirs back and measures again; the next run of the
    # same sizes finds that batch idle in the pools and takes it as it is; with less memory about,
    # after a run of other sizes (whose buffers the pools hold), or with a limit setting the
    # batch, the pools are not trusted, or not asked
    per = batching.realization_bytes(P)
    device = {"free": 40 * per, "idle": 60 * per, "released": 0}

    def release(_):
        device["free"] += device["idle"]
        device["idle"], device["released"] = 0, device["released"] + 1

    monkeypatch.setattr(batching, "is_cuda", lambda _: True)
    monkeypatch.setattr(batching, "free_bytes", lambda _: device["free"])
    monkeypatch.setattr(batching, "idle_pool_bytes", lambda _: device["idle"])
    monkeypatch.setattr(batching, "release_pools", release)
    monkeypatch.setattr(batching, "_last_sized", (None, 0))
    assert batching.default_batch(P, "cuda:0", wanted=500) == 50 and device["released"] == 1
    device.update(free=50 * per, idle=50 * per)  # the run's buffers, idle in the pools after it
    assert batching.default_batch(P, "cuda:0", wanted=500) == 50 and device["released"] == 1
    device.update(free=30 * per, idle=50 * per)  # another process took memory
    assert batching.default_batch(P, "cuda:0", wanted=500) == 40 and device["released"] == 2
    device.update(free=40 * per, idle=40 * per)
    coupled = batching.realization_bytes(P, "coupled")
    assert batching.default_batch(P, "cuda:0", wanted=500, mode="coupled") == 40 * per // coupled
    assert device["released"] == 3  # its buffers came from the decoupled run's: handed back
    device.update(free=40 * per, idle=40 * per)
    assert batching.default_batch(P, "cuda:0", wanted=500) == 40 and device["released"] == 4
    assert batching.default_batch(P, "cuda:0", memory_limit=10 * per, wanted=500) == 5 and device["released"] == 4


def test_idle_pool_memory_is_what_the_pools_keep(cuda_devices):
    # after the pools hand their memory back, a freed Warp array stays in the stream-ordered pool
    # (its release threshold keeps it) and counts as idle there, as a freed CuPy block does in CuPy's
    if not cuda_devices:
        pytest.skip("no CUDA device")
    import cupy

    from mdroll.devices import resolve_device

    size = 2**28
    for dev in cuda_devices:
        resolve_device(dev)
        batching.release_pools(dev)
        assert batching.idle_pool_bytes(dev) < size
        array = wp.empty(size // 8, dtype=wp.float64, device=dev)
        del array
        wp.synchronize_device(dev)
        assert batching.idle_pool_bytes(dev) >= size
        with cupy.cuda.Device(wp.get_device(dev).ordinal):
            block = cupy.empty(size // 8)
            del block
        assert batching.idle_pool_bytes(dev) >= 2 * size


# ============================================================================= the command line's edges
# Each case below ends in one line and exit 2, or a complete result: never a traceback, a hang, a
# silently wrong or lost result.

@pytest.fixture
def quick_plots(monkeypatch):
    """PNGs as a few bytes: the plots take most of a tiny run's second, and are not what these tests check."""
    import mdroll.plotting

    monkeypatch.setattr(mdroll.plotting, "plot_psd", lambda result, quantity, path: path.write(b"\x89PNG"))


TINY = ["--set", "L=0.025", "--set", "dx=2.5e-5", "--device", "cpu", "--no-progress"]
T = Params(L=0.025, dx=2.5e-5)


def _main(capsys, *args):
    """``mdroll args`` in this process: (exit code, stdout, stderr lines other than Warp's CUDA notice)."""
    code = cli_main([str(a) for a in args])
    captured = capsys.readouterr()
    return code, captured.out, [line for line in captured.err.splitlines() if "CUDA driver" not in line]


def _refused(capsys, needle, *args):
    code, _, err = _main(capsys, *args)
    assert code == 2 and len(err) == 1 and needle in err[0], err
    return err[0]


API_CASES_16 = [
    (lambda: contact_force(np.full((1, P.n_points), np.nan), P), "not finite"),
    (lambda: contact_force(np.full(P.n_points, np.inf), P), "not finite"),
    (lambda: contact_force(rough_lines(P, 0, 1), P, h_max=1e100), "absurd"),
    (lambda: reach(1e100, 1e-10), "absurd"),
    (lambda: run_ensemble(P, realizations=[0, 0], progress=False), "repeat"),
    (lambda: EnsembleResult.merge([]), "at least one"),
    (lambda: Params(L=1e6), "L = 1000000.0 m"),
    (lambda: Params(h0=1e100), "h0 = 1e+100"),
    (lambda: Params(h0=5e-324), "h0 = 5e-324"),  # spectra of zeros
    (lambda: Params(dx=1e-4, q_min=1e5), "dx = 0.0001 m"),
    (lambda: rough_lines(P, 0, 10**14), "realizations = 100000000000000"),
    (lambda: run_ensemble(P, realizations=COUNT, memory_limit=1000, progress=False, device="cpu"), "reduce L or increase dx"),
]


@pytest.mark.parametrize("call,needle", API_CASES_16, ids=[c[1] for c in API_CASES_16])
def test_api_refuses_absurd_input_naming_it(call, needle):
    with pytest.raises(ValueError, match=re.escape(needle)):
        call()


def test_contact_force_takes_one_line():
    lines = rough_lines(P, 0, 2)
    np.testing.assert_array_equal(contact_force(lines[0], P), contact_force(lines, P)[0])


TOML_CASES = [
    ("params = 5\n", "'params' must be a [params] table"),
    ("H = 0.5\n[params]\nL = 0.05\n", "['H'] beside the [params] table"),
    ("H = 0.5\n[run]\nseed = 3\n", "unknown table(s) ['run']"),
    ("[params]\nL = 0.05\n[params.extra]\nx = 1\n", "unknown table(s) ['extra']"),
]


@pytest.mark.parametrize("text,needle", TOML_CASES, ids=[c[1] for c in TOML_CASES])
def test_config_refuses_keys_it_would_ignore(tmp_path, capsys, text, needle):
    config = tmp_path / "c.toml"
    config.write_text(text)
    _refused(capsys, needle, "params", "--config", config)


CLI_CASES_16 = [
    (["run", "--set", "h0=1e100"], "h0 = 1e+100"),  # hung in reach()
    (["run", "--set", "h0=1e300"], "h0 = 1e+300"),  # OverflowError
    (["run", "--set", "L=1e6"], "L = 1000000.0 m"),  # Warp's "32-bit shape"
    (["params", "--set", "L=1e6"], "L = 1000000.0 m"),  # tried to allocate 744 GiB
    (["run", "--realizations", "100000000000000", *TINY], "realizations = 100000000000000"),  # MemoryError
    (["run", "--memory-limit", "inf"], "--memory-limit inf"),
    (["run", "--memory-limit", "1e-12", *TINY], "--memory-limit 1e-12 GiB"),  # was in bytes
    (["run", "--set", "dx=6e-3"], "dx = 0.006"),  # was about q_min
    (["run", "--set", "h0=1e-5", *TINY], "--force-physics"),  # h0 = 0.19 d0 ran without a word
    (["run", "--mode", "coupled", "--set", "v0=3.84e-3", "--set", "L=0.05", "--device", "cpu"], "omega_0 dt = 1.99"),  # RMS 8.4 MN, no word
    (["run", "--resume", "somewhere", "--out", "elsewhere"], "drop --out"),  # --out was ignored
]


@pytest.mark.parametrize("args,needle", CLI_CASES_16, ids=[c[1] for c in CLI_CASES_16])
def test_cli_refuses_in_one_line_naming_the_option(tmp_path, monkeypatch, capsys, args, needle):
    monkeypatch.chdir(tmp_path)
    _refused(capsys, needle, *args)
    assert not (tmp_path / "mdroll-out").exists() or not any((tmp_path / "mdroll-out").iterdir())


def test_a_batch_that_cannot_fit_is_refused_naming_it(monkeypatch):
    monkeypatch.setattr(batching, "host_available_bytes", lambda: 16 * 2**30)
    with pytest.raises(ValueError, match=r"batch = 100000 is too large for cpu: .* need 89.4 GiB"):
        run_ensemble(P, realizations=10**5, batch=10**5, device="cpu", progress=False)


def test_a_line_too_long_for_memory_is_refused_before_work(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(batching, "host_available_bytes", lambda: 16 * 2**30)
    monkeypatch.chdir(tmp_path)
    # L = 1e3 m: 2e8 springs, 17.9 GiB a realization (it computed 45 s, then failed to allocate)
    line = _refused(capsys, "reduce L or increase dx", "run", "--set", "L=1e3", "--device", "cpu")
    assert "L = 1000.0 m" in line and "17.9 GiB" in line
    assert not (tmp_path / "mdroll-out").exists()


def test_out_paths_are_checked_before_any_work(tmp_path, capsys):
    afile = tmp_path / "afile"
    afile.write_text("x")
    _refused(capsys, "is a file", "run", "--out", afile, *TINY)
    _refused(capsys, "lies under", "run", "--out", afile / "sub", *TINY)
    if os.geteuid() == 0:  # root ignores permission bits: a read-only file system instead
        if os.access("/proc", os.W_OK) and not Path("/proc/1").exists():
            pytest.skip("no read-only file system to test with")
        _refused(capsys, "cannot", "run", "--out", "/proc/mdroll-out", *TINY)
        _refused(capsys, "cannot write there", "run", "--out", "/proc/self", "--force", *TINY)
    else:
        readonly = tmp_path / "readonly"
        readonly.mkdir()
        readonly.chmod(0o555)
        _refused(capsys, "cannot write there", "run", "--out", readonly, *TINY)


def test_an_os_error_while_writing_is_one_line_naming_the_file(tmp_path, capsys, monkeypatch):
    import mdroll.plotting

    def disk_full(result, quantity, file):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(tmp_path / "run" / "accel_psd.png"))

    monkeypatch.setattr(mdroll.plotting, "plot_psd", disk_full)
    line = _refused(capsys, os.strerror(errno.ENOSPC), "run", "--out", tmp_path / "run", "--realizations", 1, *TINY)
    assert "accel_psd.png" in line


def test_a_bug_shows_as_its_traceback_not_as_bad_input(tmp_path, monkeypatch):
    import mdroll.plotting

    def broken(result, quantity, file):
        raise ValueError("a bug, not the user's input")

    monkeypatch.setattr(mdroll.plotting, "plot_psd", broken)
    with pytest.raises(ValueError, match="a bug"):
        cli_main(["run", "--out", str(tmp_path / "run"), "--realizations", "1", *TINY])


def test_a_directory_a_live_run_holds_is_refused(quick_plots, tmp_path, capsys):
    import fcntl

    out = tmp_path / "run"
    out.mkdir()
    with open(out / LOCK, "w") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        _refused(capsys, "in use by another running mdroll", "run", "--out", out, "--force", "--realizations", 1, *TINY)
    assert _main(capsys, "run", "--out", out, "--force", "--realizations", 1, *TINY)[0] == 0


def test_merge_names_the_differing_field_and_both_values(tmp_path):
    a = run_ensemble(T, realizations=[0], device="cpu", progress=False, window=False)
    b = run_ensemble(T.replace(H=0.5), realizations=[1], device="cpu", progress=False, window=False)
    w = run_ensemble(T, realizations=[2], device="cpu", progress=False, window=True)
    with pytest.raises(ValueError, match="H: 0.7 vs 0.5"):
        EnsembleResult.merge([a, b])
    # windowed with unwindowed was merged silently (PSD median 0.59x); the window survives a file
    w = EnsembleResult.load(w.save(tmp_path / "w.npz"))
    assert w.window is True
    with pytest.raises(ValueError, match="window: False vs True"):
        EnsembleResult.merge([a, w])


def _finished_run(tmp_path, capsys, name="run", *extra):
    out = tmp_path / name
    assert _main(capsys, "run", *TINY, "--realizations", 2, "--out", out, *extra)[0] == 0
    return out


def test_merge_refuses_files_that_are_not_spectra(quick_plots, tmp_path, capsys):
    out = _finished_run(tmp_path, capsys)
    data = (out / "spectra.npz").read_bytes()
    (tmp_path / "truncated.npz").write_bytes(data[: len(data) // 2])
    _refused(capsys, "truncated.npz is not an mdroll spectra file", "merge", tmp_path / "truncated.npz")
    _refused(capsys, "is a checkpoint of an unfinished run", "merge", out / CHECKPOINT)
    np.savez(tmp_path / "pickled.npz", meta=np.array([{"a": 1}], dtype=object))
    line = _refused(capsys, "pickled.npz is not an mdroll spectra file", "merge", tmp_path / "pickled.npz")
    assert "allow_pickle" not in line.split("(")[0]


def _rewrite_checkpoint(path, meta_change=None, arrays_change=None):
    meta, arrays = read_checkpoint(path)
    meta.update(meta_change or {})
    arrays.update(arrays_change or {})
    np.savez(path, meta=json.dumps(meta), **arrays)


def test_resume_refuses_a_checkpoint_it_cannot_trust(quick_plots, tmp_path, capsys):
    out = _finished_run(tmp_path, capsys)
    checkpoint = out / CHECKPOINT
    good = checkpoint.read_bytes()
    cases = [
        (lambda: checkpoint.write_bytes(b""), "cannot be read"),
        (lambda: checkpoint.write_bytes(good[: len(good) // 2]), "cannot be read"),
        (lambda: np.savez(checkpoint, other=np.zeros(2)), "cannot be read"),
        (lambda: _rewrite_checkpoint(checkpoint, arrays_change={"force_m2": np.full(3, np.nan)}), "NaN"),
        (lambda: _rewrite_checkpoint(checkpoint, {"versions": {"mdroll": "0.0.1"}}), "written by mdroll 0.0.1"),
    ]
    for spoil, needle in cases:
        checkpoint.write_bytes(good)
        spoil()
        _refused(capsys, needle, "run", "--resume", out, "--device", "cpu", "--no-progress")
    checkpoint.write_bytes(good)
    assert _main(capsys, "run", "--resume", out, "--device", "cpu", "--no-progress")[0] == 0


def test_outputs_are_written_atomically(quick_plots, tmp_path, monkeypatch, capsys):
    from mdroll.ensemble import result as result_module
    from mdroll.files import atomic_write

    target = tmp_path / "kept.txt"
    target.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_write(target, "w") as file:
            file.write("half of the new")
            raise RuntimeError("killed while writing")
    assert target.read_text() == "old" and os.listdir(tmp_path) == ["kept.txt"]

    out = _finished_run(tmp_path, capsys)
    before = (out / "spectra.npz").read_bytes()

    def dies_while_writing(file, **arrays):
        file.write(b"PK\x03\x04 a part of a zip")
        raise KeyboardInterrupt

    monkeypatch.setattr(result_module.np, "savez", dies_while_writing)
    with pytest.raises(KeyboardInterrupt):
        EnsembleResult.load(out / "spectra.npz").save(out / "spectra.npz")
    assert (out / "spectra.npz").read_bytes() == before


def test_force_into_a_finished_run_never_mixes_old_and_new(quick_plots, tmp_path, monkeypatch, capsys):
    out = _finished_run(tmp_path, capsys)

    def killed(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(pipeline, "rough_lines", killed)
    assert _main(capsys, "run", *TINY, "--realizations", 2, "--out", out, "--force", "--set", "H=0.5")[0] == 130
    assert not [p.name for p in out.iterdir() if p.name in RUN_OUTPUTS + (CHECKPOINT,)]


def test_resume_keeps_the_batch_and_checkpoints_by_time(tmp_path, monkeypatch):
    checkpoint = tmp_path / CHECKPOINT
    saves = []
    real_save = checkpoint_module.RunTotals.save

    def save_then_die(self, path, key):
        real_save(self, path, key)
        saves.append(self.done)
        if len(saves) == 2:
            raise KeyboardInterrupt

    monkeypatch.setattr(checkpoint_module.RunTotals, "save", save_then_die)
    with pytest.raises(KeyboardInterrupt):
        run_ensemble(T, realizations=7, batch=2, device="cpu", progress=False, checkpoint=checkpoint)
    assert read_checkpoint(checkpoint)[0]["batch"] == 2
    # resumed without --batch: the run's 2, not the thousands free memory allows (7.6x the memory)
    resumed = run_ensemble(T, realizations=7, device="cpu", progress=False, checkpoint=checkpoint, resume=True)
    assert resumed.batch == 2
    whole = run_ensemble(T, realizations=7, device="cpu", progress=False)
    np.testing.assert_allclose(resumed.accel_psd, whole.accel_psd, rtol=1e-12, atol=1e-12 * whole.accel_psd.max())

    # a small run that memory would take as one batch checkpoints every CHECKPOINT_SECONDS of work
    saves.clear()
    monkeypatch.setattr(checkpoint_module.RunTotals, "save", lambda self, path, key: saves.append(self.done))
    monkeypatch.setattr(pipeline, "CHECKPOINT_SECONDS", 1e-9)
    timed = run_ensemble(T, realizations=7, device="cpu", progress=False, checkpoint=tmp_path / "t.npz")
    assert saves == list(range(1, 8)) and timed.batch == 1
    assert whole.batch == 7  # without a checkpoint: one batch
    np.testing.assert_allclose(timed.force_psd, whole.force_psd, rtol=1e-12, atol=1e-12 * whole.force_psd.max())


def test_summary_records_the_run_as_it_was(quick_plots, tmp_path, capsys):
    out = _finished_run(tmp_path, capsys, "run", "--window")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["batch"] <= 2 and summary["window"] is True and summary["n_real"] == 2
    assert "n_real" not in summary["params"] and summary["physics_warnings"] == []
    assert summary["mdroll_version"] == mdroll_version
    assert read_checkpoint(out / CHECKPOINT)[0]["window"] is True


def test_physics_outside_the_model_is_flagged():
    assert validity.parameter_concerns(Params()) == []
    assert "h0 = 0.001 m" in validity.parameter_concerns(Params(h0=1e-3))[0]
    slow = Params(v0=3.84e-3)  # omega_0 dt = 1.99: stable by the bound, 8.4 MN RMS force
    assert "omega_0 dt = 1.99" in validity.parameter_concerns(slow)[0]
    assert validity.parameter_concerns(Params(v0=0.016)) == []  # omega_0 dt = 0.48: a 0.95 % shift
    resolved = Resolution({"force": np.full(8, -1), "accel": np.full(8, -1)})
    lost = type("R", (), {"params": Params(), "n_real": 2, "steps": 1000, "contact_lost_steps": 21,
                          "window": True, "resolution": resolved})()
    assert "contact was lost (F = 0) on 21 of 2000 steps" in validity.result_concerns(lost)[0]
    lost.contact_lost_steps = 20
    assert validity.result_concerns(lost) == []


def test_forced_physics_runs_and_says_so(quick_plots, tmp_path, capsys):
    code, _, err = _main(capsys, "run", *TINY, "--set", "h0=1e-5", "--force-physics", "--realizations", 1,
                         "--out", tmp_path / "r")
    assert code == 0 and err and all(line.startswith("mdroll: warning: h0 = 1e-05 m") for line in err)
    warnings = json.loads((tmp_path / "r" / "summary.json").read_text())["physics_warnings"]
    assert warnings and warnings[0].startswith("h0 = 1e-05 m")


def test_closed_pipe_ends_quietly(monkeypatch, capsys):
    class ClosedPipe:
        def write(self, text):
            raise BrokenPipeError(32, "Broken pipe")

        def flush(self):
            raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr(sys, "stdout", ClosedPipe())
    assert cli_main(["params"]) == 141
    assert "Traceback" not in capsys.readouterr().err


def test_a_non_finite_force_ends_the_cli_in_one_line(tmp_path, monkeypatch, capsys):
    real = pipeline.rough_lines

    def poisoned(params, seed, idx, device, **options):
        lines = np.array(real(params, seed, idx, device=device, **options))
        lines[0, 10] = np.nan
        return lines

    monkeypatch.setattr(pipeline, "rough_lines", poisoned)
    _refused(capsys, "force is not finite in realization 0", "run", *TINY, "--realizations", 1, "--out", tmp_path / "r")


def test_sigterm_unwinds_keeping_the_checkpoint(tmp_path):
    """A scheduler's SIGTERM: one line, exit 143, the checkpoint kept, no temporary file left."""
    out = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "-m", "mdroll", "run", *TINY, "--realizations", "100000", "--batch", "1",
                             "--out", str(out)], cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while time.time() < deadline and not (out / CHECKPOINT).exists():
        time.sleep(0.02)
    proc.send_signal(signal.SIGTERM)
    err = [line for line in proc.communicate(timeout=60)[1].splitlines() if "CUDA driver" not in line]
    assert proc.returncode == 143 and err == ["mdroll: terminated; continue with mdroll run --resume DIR"], err
    assert read_checkpoint(out / CHECKPOINT)[0]["done"] >= 1
    assert sorted(p.name for p in out.iterdir()) == [LOCK, CHECKPOINT]
