"""Where does a warm thesis-scale run spend the time outside its stages? (300 x 2^20, edge)

For each case: the run's wall time, the sum of its stage timings, the waits of every device
synchronization the pipeline makes (before/after each stage), and a cProfile of one run's host
functions by own time. Cases: edge alone (fresh process state), edge after tree and direct runs,
and both again with Warp's stream-ordered pool told to keep its memory (release threshold =
device memory) instead of handing it back to the driver at each synchronization.

    python benchmarks/probes/overhead_probe.py --out overhead.json
"""
import argparse
import cProfile
import io
import json
import pstats
import time

from mdroll import Params, run_ensemble
from mdroll.devices import warp
from mdroll.ensemble import pipeline

wp = warp()
DEVICE = "cuda:0"
P = Params(L=5.24288, n_real=300)
waits = []
_sync = pipeline.synchronize


def traced_sync(device):
    t = time.perf_counter()
    _sync(device)
    waits.append(time.perf_counter() - t)


pipeline.synchronize = traced_sync


def one(algorithm):
    waits.clear()
    wp.synchronize_device(DEVICE)
    t = time.perf_counter()
    result = run_ensemble(P, algorithm=algorithm, device=DEVICE, progress=False)
    wp.synchronize_device(DEVICE)
    total = time.perf_counter() - t
    return {"total_ms": 1e3 * total, "stages_ms": 1e3 * sum(result.timings.values()),
            "sync_waits_ms": [round(1e3 * w, 3) for w in waits],
            "used_mempool_GiB": wp.get_mempool_used_mem_current(DEVICE) / 2**30}


def case(name, record):
    runs = [one("edge") for _ in range(3)]
    profile = cProfile.Profile()
    profile.enable()
    run_ensemble(P, algorithm="edge", device=DEVICE, progress=False)
    wp.synchronize_device(DEVICE)
    profile.disable()
    text = io.StringIO()
    pstats.Stats(profile, stream=text).sort_stats("tottime").print_stats(18)
    record[name] = {"runs": runs, "profile": text.getvalue()}
    print(name, [(round(r["total_ms"], 1), round(r["stages_ms"], 1)) for r in runs], flush=True)
    print(runs[-1]["sync_waits_ms"], flush=True)
    print(text.getvalue()[:3000], flush=True)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", default="overhead.json")
    args = parser.parse_args()
    record = {"release_threshold_default": wp.get_mempool_release_threshold(DEVICE)}
    print("release threshold", record["release_threshold_default"], flush=True)
    one("edge")
    case("edge_alone", record)
    for algorithm in ("tree", "direct"):
        one(algorithm)
    case("edge_after_tree_direct", record)
    wp.set_mempool_release_threshold(DEVICE, wp.get_device(DEVICE).total_memory)
    case("edge_after_keep_pool", record)
    for algorithm in ("tree", "direct"):
        one(algorithm)
    case("edge_after_tree_direct_keep_pool", record)
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
