"""The Dask runner (mdroll.distributed) gives the one-process answer, survives a killed worker and
resumes from its checkpoint: a local cluster of 2 worker processes on the CPU, as on CI."""

import os
import signal
import threading
import time

import numpy as np
import pytest

pytest.importorskip("distributed")

from mdroll.errors import ParameterError  # noqa: E402
from mdroll import EnsembleSpec, Params, run_specs  # noqa: E402
from mdroll.distributed import DaskRunner, default_unit_size, local_cluster, work_units  # noqa: E402

FIELDS = ("force_psd", "force_psd_stderr", "accel_psd", "accel_psd_stderr")


def specs():
    base = Params(L=0.1)
    return [EnsembleSpec(base, seed=7, first=3, realizations=5),
            EnsembleSpec(base.replace(H=0.5), seed=7, realizations=3, boundary="periodic")]


@pytest.fixture(scope="module")
def client():
    client = local_cluster(2, device="cpu")
    yield client
    client.close()
    client.cluster.close()


@pytest.fixture(scope="module")
def reference():
    return run_specs(specs(), device="cpu")


def assert_same(results, references):
    assert len(results) == len(references)
    for result, reference in zip(results, references):
        assert result.n_real == reference.n_real
        assert sorted(result.realizations) == sorted(reference.realizations)
        for name in FIELDS:
            got, want = getattr(result, name), getattr(reference, name)
            assert np.max(np.abs(got - want)) <= 1e-12 * np.max(np.abs(want)), name
        assert result.force_mean == pytest.approx(reference.force_mean, rel=1e-12)
        assert result.force_rms == pytest.approx(reference.force_rms, rel=1e-12)


def test_work_units_cover_each_realization_once():
    units = work_units(specs(), 2)
    assert [u.uid for u in units] == ["0-3-2", "0-5-2", "0-7-1", "1-0-2", "1-2-1"]
    assert default_unit_size(specs(), workers=2) == 1  # 8 realizations, 4 units per worker
    assert default_unit_size(specs(), workers=1) == 2
    with pytest.raises(ParameterError, match="unit_size"):
        DaskRunner(client=None, unit_size=0)
    with pytest.raises(ParameterError, match="workers"):
        local_cluster(0, device="cpu")


@pytest.mark.parametrize("unit_size", [1, 3])
def test_cluster_equals_one_process(client, reference, unit_size):
    results = run_specs(specs(), device="cpu", runner=DaskRunner(client, unit_size=unit_size))
    assert_same(results, reference)


def test_killed_worker_loses_and_doubles_nothing(client, reference):
    runner = DaskRunner(client, unit_size=1)
    pids = client.run(os.getpid)  # worker address -> process id
    killed = []

    def kill_a_busy_worker():
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            busy = [w for w, tasks in client.processing().items() if tasks]
            if busy:
                os.kill(pids[busy[0]], signal.SIGKILL)
                killed.append(busy[0])
                return
            time.sleep(0.01)

    killer = threading.Thread(target=kill_a_busy_worker)
    killer.start()
    results = run_specs(specs(), device="cpu", runner=runner)
    killer.join()
    assert killed, "no worker was busy to be killed"
    assert_same(results, reference)


def test_checkpoint_resumes_only_missing_units(client, reference, tmp_path):
    runner = DaskRunner(client, unit_size=2, checkpoint=tmp_path)
    assert_same(runner.run_specs(specs(), device="cpu"), reference)
    files = sorted(tmp_path.glob("unit-*.npz"))
    assert [f.name for f in files] == [f"unit-{u}.npz" for u in sorted(["0-3-2", "0-5-2", "0-7-1", "1-0-2", "1-2-1"])]
    kept = {f.name: f.stat().st_mtime_ns for f in files[1:]}
    files[0].unlink()  # a unit lost: only it is computed again
    assert_same(runner.run_specs(specs(), device="cpu"), reference)
    assert files[0].exists()
    assert {f.name: f.stat().st_mtime_ns for f in files[1:]} == kept
    other = [EnsembleSpec(Params(L=0.1), seed=8, realizations=2)]
    with pytest.raises(ParameterError, match="another distributed run"):
        runner.run_specs(other, device="cpu")


def test_cli_workers_equal_one_process(tmp_path, capsys):
    from mdroll.cli import main
    from mdroll.ensemble.result import EnsembleResult

    common = ["run", "--set", "L=0.1", "--realizations", "4", "--first", "2", "--seed", "5", "--device", "cpu",
              "--no-progress"]
    assert main(common + ["--out", str(tmp_path / "local")]) == 0
    assert main(common + ["--workers", "2", "--out", str(tmp_path / "dask")]) == 0
    assert_same([EnsembleResult.load(tmp_path / "dask" / "spectra.npz")],
                [EnsembleResult.load(tmp_path / "local" / "spectra.npz")])
    assert len(list((tmp_path / "dask" / "units").glob("unit-*.npz"))) == 4  # 4 realizations, 2 workers
    # the finished units are kept: resuming recomputes nothing and gives the same spectra
    assert main(["run", "--resume", str(tmp_path / "dask"), "--workers", "2", "--device", "cpu", "--no-progress"]) == 0
    capsys.readouterr()
    for bad, named in [(["--workers", "0"], "workers"), (["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "not both")]:
        assert main(common + bad + ["--out", str(tmp_path / "bad")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and named in err[0]
