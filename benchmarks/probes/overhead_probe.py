"""Where does a warm thesis-scale run spend the time outside its stages? (300 x 2^20, edge)

Since v7 the pipeline does not synchronize around its stages: a stage's time is the device's,
between two CUDA events, and the host queues the next stage while the device runs. For each
run: the wall time, the sum of the stage timings, and the host's wall time inside each stage's
call (it returns once the stage is queued, unless something in it waits for the device); then
a cProfile of one run's host functions by own time. The device timeline comes from CUDA events:
one queued just before the call, the stages' own, two around the result's computation and copy
(``_Totals.spectra_on_host``) and one queued after the call returns; the gaps between them are
the device's idle time (or work outside the stages).

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
marks = []  # (label, CUDA event) in stream order
_queue_stage = pipeline._StageClock.__call__
_spectra_on_host = pipeline._Totals.spectra_on_host


def mark(label):
    event = wp.Event(DEVICE, enable_timing=True)
    wp.get_stream(DEVICE).record_event(event)
    marks.append((label, event))


def traced_stage(self, name, fn):
    t = time.perf_counter()
    out = _queue_stage(self, name, fn)
    host_ms.append((name, round(1e3 * (time.perf_counter() - t), 3)))
    if self.pending:
        _, start, end = self.pending[-1]
        marks.extend([(f"{name} start", start), (f"{name} end", end)])
    return out


def traced_spectra_on_host(self, params, **kwargs):
    mark("result start")
    out = _spectra_on_host(self, params, **kwargs)
    mark("result copied")
    return out


pipeline._StageClock.__call__ = traced_stage
pipeline._Totals.spectra_on_host = traced_spectra_on_host


def timeline():
    """Device milliseconds from each mark to the next."""
    return [(f"{a} -> {b}", round(wp.get_event_elapsed_time(ea, eb), 3)) for (a, ea), (b, eb) in zip(marks, marks[1:])]


def one(algorithm):
    host_ms.clear()
    marks.clear()
    wp.synchronize_device(DEVICE)
    t = time.perf_counter()
    mark("call")
    result = run_ensemble(P, algorithm=algorithm, device=DEVICE, progress=False)
    mark("returned")
    wp.synchronize_device(DEVICE)
    total = time.perf_counter() - t
    return {"total_ms": 1e3 * total, "stages_ms": {k: 1e3 * v for k, v in result.timings.items()},
            "stages_sum_ms": 1e3 * sum(result.timings.values()), "host_ms_per_stage_call": list(host_ms),
            "device_timeline_ms": timeline()}


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
        print([entry for entry in last["device_timeline_ms"] if "->" in entry[0] and (
            " end -> " in entry[0] or entry[0].startswith(("call", "result")))], flush=True)
        print(text.getvalue()[:4500], flush=True)
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
