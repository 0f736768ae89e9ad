"""The Dask runner (mdroll.distributed) gives the one-process answer on any number of workers,
survives a worker killed with SIGKILL, resumes from its checkpoint and ends a lost scheduler in
one line: local clusters of worker processes on the CPU, as on CI."""

import contextlib
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("distributed")

from distributed import Client, LocalCluster  # noqa: E402

from mdroll import EnsembleSpec, Params, run_specs  # noqa: E402
from mdroll.errors import ParameterError  # noqa: E402
from mdroll.distributed import (DaskRunner, default_unit_size, local_cluster, merge_parts, part_of,  # noqa: E402
                                result_of, run_unit, work_units)

FIELDS = ("force_psd", "force_psd_stderr", "accel_psd", "accel_psd_stderr")
#: The merge of per-worker partial means and variances in another order than one process's
#: batches differs from it by rounding only: a few ulps of the spectra.
RELATIVE = 1e-12


def specs():
    base = Params(L=0.1)
    return [EnsembleSpec(base, seed=7, first=3, realizations=5),
            EnsembleSpec(base.replace(H=0.5), seed=7, realizations=3, boundary="periodic")]


@pytest.fixture(scope="module")
def cluster():
    """Three worker processes of one thread (more than the cores of CI: a cluster a user brings
    is not bounded by this machine), scaled down by the tests that need fewer."""
    cluster = LocalCluster(n_workers=3, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address=None, silence_logs=40, memory_limit=0)
    client = Client(cluster)
    yield cluster, client
    client.close()
    # a worker the killed-worker test ended on purpose can be missing from the cluster's spec,
    # which LocalCluster.close reports as a KeyError of its address
    with contextlib.suppress(KeyError):
        cluster.close()


@pytest.fixture(scope="module")
def reference():
    return run_specs(specs(), device="cpu")


def assert_same(results, references):
    assert len(results) == len(references)
    for result, reference in zip(results, references):
        assert result.n_real == reference.n_real
        assert result.realizations == reference.realizations
        for name in FIELDS:
            got, want = getattr(result, name), getattr(reference, name)
            assert np.max(np.abs(got - want)) <= RELATIVE * np.max(np.abs(want)), name
        assert result.force_mean == pytest.approx(reference.force_mean, rel=RELATIVE)
        assert result.force_rms == pytest.approx(reference.force_rms, rel=RELATIVE)


def test_units_are_whole_batches_and_cover_each_realization_once():
    units = work_units(specs(), 2)
    assert [u.uid for u in units] == ["0-3-2", "0-5-2", "0-7-1", "1-0-2", "1-2-1"]
    assert [u.uid for u in work_units(specs(), [5, 1])] == ["0-3-5", "1-0-1", "1-1-1", "1-2-1"]
    # one unit a worker: its whole share
    assert default_unit_size(1200, workers=2) == 600
    assert default_unit_size(1201, workers=2) == 601
    assert default_unit_size(6000, workers=4) == 1500
    assert default_unit_size(1200, workers=1) == 1200
    assert default_unit_size(3, workers=4) == 1
    with pytest.raises(ParameterError, match="unit_size"):
        DaskRunner(client=None, unit_size=0)
    with pytest.raises(ParameterError, match="workers"):
        local_cluster(0, device="cpu")
    with pytest.raises(ParameterError, match=f"at most {os.cpu_count() and len(os.sched_getaffinity(0))}, one CPU"):
        local_cluster(len(os.sched_getaffinity(0)) + 1, device="cpu")


def test_parts_merge_to_the_sample_moments_and_travel_as_one_array(tmp_path):
    from distributed.protocol import serialize

    spec = EnsembleSpec(Params(L=0.1), seed=7, first=3, realizations=5)
    parts = [part_of(unit.run(device="cpu"), unit.first) for unit in spec.split(2)]
    merged = result_of(merge_parts(*parts[::-1]))
    assert merged.realizations == [3, 4, 5, 6, 7] and merged.n_real == 5
    assert_same([merged], [spec.run(device="cpu")])
    # against numpy's mean and standard error over the realizations' own spectra
    singles = [unit.run(device="cpu") for unit in spec.split(1)]
    for name in ("force_psd", "accel_psd"):
        rows = np.stack([getattr(r, name) for r in singles])
        for got, want in ((getattr(merged, name), rows.mean(axis=0)),
                          (getattr(merged, name + "_stderr"), rows.std(axis=0, ddof=1) / np.sqrt(5))):
            assert np.max(np.abs(got - want)) <= RELATIVE * np.max(want), name
    with pytest.raises(ParameterError, match="share realization 3"):
        merge_parts(parts[0], parts[0])
    # the spectra go as one frame of their bytes; the rest (settings, spans) is small whatever the count
    frames = [memoryview(f).nbytes for f in serialize(merge_parts(*parts))[1]]
    assert frames.count(4 * merged.q.size * 8) == 1 and sum(frames) - 4 * merged.q.size * 8 < 4096, frames
    with pytest.raises(ParameterError, match="not visible to every worker"):
        run_unit(spec, "cpu", {}, str(tmp_path / "elsewhere"))


def test_a_runs_part_is_its_own_rows_and_any_other_a_copy(device):
    import dataclasses

    result = EnsembleSpec(Params(L=0.05), seed=7, realizations=2).run(device=device)
    spectra, _, spans = part_of(result, 0)
    assert spans == ((0, 2),)
    want = np.stack([getattr(result, name) for name in FIELDS])
    np.testing.assert_array_equal(spectra, want)
    assert np.shares_memory(spectra, result.force_psd)  # no copy of the bins before sending
    # rows of a flat buffer, as CuPy's page-locked copy gives them on every device's host
    names = ("q", "omega") + FIELDS
    flat = np.frombuffer(bytearray(len(names) * result.q.nbytes), np.float64)
    rows = tuple(flat.reshape(len(names), -1))
    for row, name in zip(rows, names):
        row[:] = getattr(result, name)
    spectra = part_of(dataclasses.replace(result, **dict(zip(names, rows))), 0)[0]
    np.testing.assert_array_equal(spectra, want)
    assert np.shares_memory(spectra, flat)
    # the rows of one array out of order or one reversed, or the rows apart: the part is a copy
    # in the order of SPECTRA
    others = [dataclasses.replace(result, force_psd=result.accel_psd, accel_psd=result.force_psd),
              dataclasses.replace(result, force_psd=result.force_psd[::-1]),
              dataclasses.replace(result, **{name: getattr(result, name).copy() for name in FIELDS})]
    for other in others:
        rows = part_of(other, 0)[0]
        np.testing.assert_array_equal(rows, np.stack([getattr(other, name) for name in FIELDS]))
        assert not np.shares_memory(rows, result.force_psd.base)


def test_local_cluster_gathers_directly_from_quiet_workers():
    import dask

    client = local_cluster(1, device="cpu")
    try:
        assert client.direct_to_workers is True  # the parts come from the workers, not via the scheduler
        assert list(client.run(lambda: dask.config.get("distributed.worker.profile.enabled")).values()) == [False]
        assert list(client.run(lambda: os.environ["OMP_NUM_THREADS"]).values()) == ["1"]
    finally:
        client.close()
        client.cluster.close()


def scale(cluster, workers):
    cluster, client = cluster
    cluster.scale(workers)
    client.wait_for_workers(workers)
    while len(client.scheduler_info()["workers"]) > workers:
        time.sleep(0.05)


@pytest.mark.parametrize("workers", [3, 2])
def test_any_number_of_workers_equals_one_process(cluster, reference, workers):
    scale(cluster, workers)
    _, client = cluster
    for unit_size in (None, 3):
        assert_same(run_specs(specs(), device="cpu", runner=DaskRunner(client, unit_size=unit_size)), reference)


@pytest.mark.parametrize("unit_size", [1, None])
def test_killed_worker_loses_and_doubles_nothing(cluster, reference, unit_size):
    """Units merged on the workers (several a spec) and parts taken by the client as their units
    end (one a worker)."""
    _, client = cluster
    runner = DaskRunner(client, unit_size=unit_size)
    pids = client.run(os.getpid)  # worker address -> process id
    killed = []

    def kill_a_busy_worker():
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            busy = [w for w, tasks in client.processing().items()
                    if any(str(t).startswith("mdroll-unit") for t in tasks)]
            if busy:
                os.kill(pids[busy[0]], signal.SIGKILL)
                killed.append(busy[0])
                return
            time.sleep(0.005)

    killer = threading.Thread(target=kill_a_busy_worker)
    killer.start()
    results = run_specs(specs(), device="cpu", runner=runner)
    killer.join()
    assert killed, "no worker was busy to be killed"
    assert_same(results, reference)


def test_one_worker_equals_one_process(cluster, reference):
    scale(cluster, 1)
    assert_same(run_specs(specs(), device="cpu", runner=DaskRunner(cluster[1])), reference)


def test_checkpoint_resumes_only_missing_units(cluster, reference, tmp_path):
    _, client = cluster
    runner = DaskRunner(client, unit_size=2, checkpoint=tmp_path)
    assert_same(runner.run_specs(specs(), device="cpu"), reference)
    files = sorted(tmp_path.glob("unit-*.npz"))
    assert [f.name for f in files] == [f"unit-{u}.npz" for u in sorted(["0-3-2", "0-5-2", "0-7-1", "1-0-2", "1-2-1"])]
    kept = {f.name: f.stat().st_mtime_ns for f in files[1:]}
    files[0].unlink()  # a unit lost: only it is computed again, with the run's unit sizes
    assert_same(DaskRunner(client, unit_size=3, checkpoint=tmp_path).run_specs(specs(), device="cpu"), reference)
    assert files[0].exists()
    assert {f.name: f.stat().st_mtime_ns for f in files[1:]} == kept
    other = [EnsembleSpec(Params(L=0.1), seed=8, realizations=2)]
    with pytest.raises(ParameterError, match="another distributed run"):
        runner.run_specs(other, device="cpu")
    (tmp_path / "unit-0-3-2.npz").write_bytes((tmp_path / "unit-0-5-2.npz").read_bytes())
    with pytest.raises(ParameterError, match="does not hold the realizations 3 to 4"):
        runner.run_specs(specs(), device="cpu")


def test_cli_workers_equal_one_process_and_resume_keeps_the_run(cluster, tmp_path, capfd):
    from mdroll.cli import main
    from mdroll.ensemble.result import EnsembleResult

    common = ["run", "--set", "L=0.1", "--realizations", "4", "--first", "2", "--seed", "5", "--device", "cpu",
              "--no-progress"]
    assert main(common + ["--out", str(tmp_path / "local")]) == 0
    capfd.readouterr()
    assert main(common + ["--workers", "1", "--out", str(tmp_path / "dask")]) == 0
    err = capfd.readouterr().err
    assert "INFO" not in err, err  # Dask's logs only with --verbose
    assert_same([EnsembleResult.load(tmp_path / "dask" / "spectra.npz")],
                [EnsembleResult.load(tmp_path / "local" / "spectra.npz")])
    assert len(list((tmp_path / "dask" / "units").glob("unit-*.npz"))) == 1  # 4 realizations fill one batch
    resume = ["run", "--resume", str(tmp_path / "dask"), "--device", "cpu", "--no-progress"]
    # a resumed run is the same run: what would change it is refused, naming it, before any cluster starts
    for bad, named in [(["--set", "H=0.5"], "H: 0.7 -> 0.5"), (["--realizations", "6"], "realizations: 4 -> 6"),
                       (["--seed", "6"], "seed: 5 -> 6"), (["--out", str(tmp_path / "x")], "drop --out")]:
        assert main(resume + ["--workers", "2"] + bad) == 2
        lines = capfd.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and named in lines[0], lines
    # the finished units are kept: resuming (on another cluster) recomputes nothing
    units = {p: p.stat().st_mtime_ns for p in (tmp_path / "dask" / "units").glob("unit-*.npz")}
    assert main(resume + ["--scheduler", cluster[0].scheduler_address]) == 0
    assert {p: p.stat().st_mtime_ns for p in units} == units
    for bad, named in [(["--workers", "0"], "workers"), (["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "not both"),
                       (["--workers", str(len(os.sched_getaffinity(0)) + 1)], "one CPU worker per core")]:
        assert main(common + bad + ["--out", str(tmp_path / "bad")]) == 2
        err = capfd.readouterr().err.strip().splitlines()
        assert len(err) == 1 and named in err[0], err


HIDE_DASK = """
import sys
class Hide:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in ("distributed", "dask"):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
sys.meta_path.insert(0, Hide())
from mdroll.cli import main
for option in (["--workers", "2"], ["--scheduler", "tcp://127.0.0.1:1"]):
    print(main(sys.argv[1:] + option))
"""


def test_cluster_options_without_dask_are_one_line(tmp_path):
    run = subprocess.run([sys.executable, "-c", HIDE_DASK, "run", "--set", "L=0.1", "--realizations", "2",
                          "--device", "cpu", "--out", str(tmp_path / "o"), "--force"],
                         capture_output=True, text=True, timeout=120)
    assert run.stdout.split() == ["2", "2"], run.stdout + run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 2, run.stderr
    for option, line in zip(("--workers", "--scheduler"), lines):
        assert line.endswith(f"{option} needs Dask distributed, which is not installed: pip install 'mdroll[distributed]'")


def test_killed_scheduler_is_one_line_and_keeps_the_run(tmp_path, capfd):
    from mdroll.cli import main

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        address = f"tcp://127.0.0.1:{s.getsockname()[1]}"
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).parents[1]))
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL, "env": env}
    scheduler = subprocess.Popen(["dask", "scheduler", "--host", "127.0.0.1", "--port", address.rsplit(":", 1)[1],
                                  "--no-dashboard"], **quiet)
    worker = subprocess.Popen(["dask", "worker", address, "--nthreads", "1", "--no-dashboard"], **quiet)
    out = tmp_path / "run"
    manifest = out / "units" / "manifest.json"

    def kill_when_the_units_run():
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and not (manifest.exists() and '"sizes": [' in manifest.read_text()):
            time.sleep(0.02)
        scheduler.send_signal(signal.SIGKILL)

    killer = threading.Thread(target=kill_when_the_units_run)
    try:
        killer.start()
        code = main(["run", "--set", "L=1", "--realizations", "400", "--device", "cpu", "--no-progress",
                     "--scheduler", address, "--out", str(out)])
        killer.join()
    finally:
        scheduler.kill()
        worker.kill()
        scheduler.wait()
        worker.wait()
    lines = capfd.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1, lines
    assert f"lost the Dask scheduler at {address}" in lines[0]
    assert f"continue with: mdroll run --resume {out} --scheduler {address}" in lines[0]
    assert manifest.exists()
