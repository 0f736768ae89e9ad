"""Where does a warm thesis-scale run spend the time outside its stages? (300 x 2^20, edge)

Since v7 the pipeline does not synchronize around its stages: a stage's time is the device's,
between two CUDA events, and the host queues the next stage while the device runs. For each
run: the wall time, the sum of the stage timings, and the host's wall time inside each stage's
call (it returns once the stage is queued, unless something in it waits for the device); then
a cProfile of one run's host functions by own time.

    python benchmarks/probes/overhead_probe.py --out overhead.json

(results/overhead_probe_H200.json and _v6.json came from the earlier form of this probe, which
timed the synchronizations around every stage.)
"""
import argparse
import cProfile
import io
import json
import pstats
import time

from mdroll import Params, run_ensemble
from mdroll.devices import resolve_device, warp
from mdroll.ensemble import pipeline

wp = warp()
DEVICE = "cuda:0"
P = Params(L=5.24288, n_real=300)
host_ms = []
_queue_stage = pipeline._StageClock.__call__


def traced_stage(self, name, fn):
    t = time.perf_counter()
    out = _queue_stage(self, name, fn)
    host_ms.append((name, round(1e3 * (time.perf_counter() - t), 3)))
    return out


pipeline._StageClock.__call__ = traced_stage


def one(algorithm):
    host_ms.clear()
    wp.synchronize_device(DEVICE)
    t = time.perf_counter()
    result = run_ensemble(P, algorithm=algorithm, device=DEVICE, progress=False)
    wp.synchronize_device(DEVICE)
    total = time.perf_counter() - t
    return {"total_ms": 1e3 * total, "stages_ms": {k: 1e3 * v for k, v in result.timings.items()},
            "stages_sum_ms": 1e3 * sum(result.timings.values()), "host_ms_per_stage_call": list(host_ms)}


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", default="overhead.json")
    args = parser.parse_args()
    resolve_device(DEVICE)
    record = {}
    for algorithm in ("edge", "tree"):
        one(algorithm)
        runs = [one(algorithm) for _ in range(3)]
        profile = cProfile.Profile()
        profile.enable()
        run_ensemble(P, algorithm=algorithm, device=DEVICE, progress=False)
        wp.synchronize_device(DEVICE)
        profile.disable()
        text = io.StringIO()
        pstats.Stats(profile, stream=text).sort_stats("tottime").print_stats(25)
        record[algorithm] = {"runs": runs, "profile": text.getvalue()}
        last = runs[-1]
        print(algorithm, [(round(r["total_ms"], 1), round(r["stages_sum_ms"], 1)) for r in runs], flush=True)
        print(last["host_ms_per_stage_call"], flush=True)
        print(text.getvalue()[:4500], flush=True)
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
