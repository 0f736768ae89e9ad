"""Scale-out of the Dask runner (mdroll.distributed) against one GPU in a process of its own:
per workload, the warm wall time in process, on a local cluster of one worker and of two (one
per GPU, pinned), and the largest relative difference of the cluster's spectra from the
in-process run's.

    python benchmarks/scaleout.py --device cuda:0 --out scaleout.json

Workloads at thesis scale (2^20 springs, open boundary, the mode's default algorithm): the
decoupled sweep of 6000 realizations, the coupled run of 1200, and runs of each mode sized to take
about one and five seconds in process (from that mode's first workload's rate). The in-process run goes in a
spawned child that exits before any cluster starts, so that no GPU memory of this process
shrinks a worker's batches; every run is timed after a small warm-up of its kernels (the
clusters' start-up and warm-up are recorded beside). ``--small`` runs the same at a size for the
CPU (``--device cpu``: worker processes of one core each). Each cluster run also records where its
time went: the client's probe of the batches and final reduction, and per task kind (unit, merge)
the workers' compute and transfer seconds (Dask's task stream). Dask is imported in ``main`` only.
"""

import argparse
import contextlib
import dataclasses
import json
import multiprocessing
import subprocess
import time
from pathlib import Path

import numpy as np

FIELDS = ("force_psd", "force_psd_stderr", "accel_psd", "accel_psd_stderr")
#: (name, mode, realizations or in-process seconds) at thesis scale: the first workload of each
#: mode is counted in realizations and gives that mode's rate, from which the others are sized to
#: take about their seconds in process (the targets are stated at one and at five seconds).
WORKLOADS = (("decoupled-6000", "decoupled", 6000), ("coupled-1200", "coupled", 1200),
             ("decoupled-1s", "decoupled", 1.0), ("decoupled-5s", "decoupled", 5.0),
             ("coupled-1s", "coupled", 1.0), ("coupled-5s", "coupled", 5.0))
THESIS_L = 5.24288  # m: 2^20 springs of 5 um
SMALL = {"L": 0.1, "decoupled": 48, "coupled": 16}
WARM_UP_L = 0.05


def sized(spec, name: str, rates: dict, small: bool):
    """The workload ``name``'s spec: its own count, or its seconds at its mode's measured rate."""
    mode, amount = next((m, a) for n, m, a in WORKLOADS if n == name)
    if isinstance(amount, int):
        return dataclasses.replace(spec, realizations=SMALL[mode] if small else amount)
    count = max(2, int(round(rates[mode] * amount, 0 if small else -1)))
    return dataclasses.replace(spec, realizations=count)


def specs_for(small: bool):
    from mdroll import EnsembleSpec, Params

    L = SMALL["L"] if small else THESIS_L
    return {name: EnsembleSpec(Params(L=L), seed=0, realizations=1, mode=mode) for name, mode, _ in WORKLOADS}


def warm_up(spec, run) -> float:
    """Run a short copy of ``spec`` (its kernels loaded, its FFTs planned); its seconds."""
    from mdroll import Params

    t0 = time.perf_counter()
    run(dataclasses.replace(spec, params=Params(L=WARM_UP_L), realizations=8))
    return time.perf_counter() - t0


def in_process(device: str, small: bool) -> dict:
    """In a spawned child: each workload's warm wall time and spectra on ``device`` (the sized
    ones from their mode's first workload's rate, :func:`sized`), and the environment."""
    from mdroll import run_specs
    from mdroll.provenance import environment

    out = {"environment": environment(device), "runs": {}}
    rates = {}
    for name, spec in specs_for(small).items():
        spec = sized(spec, name, rates, small)
        warm_up(spec, lambda s: run_specs([s], device=device))
        t0 = time.perf_counter()
        (result,) = run_specs([spec], device=device)
        out["runs"][name] = {"wall_s": time.perf_counter() - t0, "spec": spec.as_dict(),
                             "spectra": {f: getattr(result, f) for f in FIELDS}}
        rates.setdefault(spec.mode, spec.realizations / out["runs"][name]["wall_s"])
        print(f"{name}: in process {out['runs'][name]['wall_s']:.3f} s", flush=True)
    return out


def largest_difference(result, reference: dict) -> float:
    return max(float(np.max(np.abs(getattr(result, f) - reference[f])) / np.max(np.abs(reference[f]))) for f in FIELDS)


@contextlib.contextmanager
def phase_clock(runner):
    """The client's seconds in the runner's probe of the workers' batches and in the final
    reduction, by wrapping the two methods of this runner for the duration."""
    phases = {"batches_s": 0.0, "reduce_s": 0.0}
    originals = {}
    for name, key in (("_batches", "batches_s"), ("_reduce_on_workers", "reduce_s")):
        method = originals[name] = getattr(runner, name)

        def timed(*a, _method=method, _key=key, **k):
            t0 = time.perf_counter()
            try:
                return _method(*a, **k)
            finally:
                phases[_key] += time.perf_counter() - t0
        setattr(runner, name, timed)
    try:
        yield phases
    finally:
        for name in originals:
            delattr(runner, name)


def task_summary(tasks: list, t_submit: float) -> dict:
    """Per task kind (the key's second word: unit, merge, batches), the tasks' count, their
    compute and transfer seconds summed, and the first start and last end relative to the
    earliest task start (each worker's clock)."""
    out = {}
    starts = [s["start"] for t in tasks for s in t["startstops"]]
    origin = min(starts) if starts else 0.0
    for t in tasks:
        kind = str(t["key"]).split("-")[1] if "-" in str(t["key"]) else "other"
        entry = out.setdefault(kind, {"count": 0, "compute_s": 0.0, "transfer_s": 0.0, "first_start_s": None,
                                      "last_stop_s": 0.0})
        entry["count"] += 1
        for s in t["startstops"]:
            entry[f"{s['action']}_s"] = entry.get(f"{s['action']}_s", 0.0) + s["stop"] - s["start"]
            first = entry["first_start_s"]
            entry["first_start_s"] = s["start"] - origin if first is None else min(first, s["start"] - origin)
            entry["last_stop_s"] = max(entry["last_stop_s"], s["stop"] - origin)
    return {"tasks": out}


def commit() -> str:
    try:
        proc = subprocess.run(["git", "rev-parse", "HEAD"], cwd=Path(__file__).parent, capture_output=True, text=True)
    except OSError:
        return "unknown"
    return proc.stdout.strip() or "unknown"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda:0", help="cuda:0 (one worker per GPU) or cpu")
    parser.add_argument("--workers", type=int, default=2, help="the larger cluster (default 2)")
    parser.add_argument("--small", action="store_true", help="a size for the CPU: L = 0.1 m, few realizations")
    parser.add_argument("--commit", help="the commit measured (default: git rev-parse HEAD, where there is a .git)")
    parser.add_argument("--out", default="scaleout.json")
    args = parser.parse_args()
    import distributed  # imported here: the clusters' machine may carry Dask apart from the package

    from mdroll import EnsembleSpec
    from mdroll.distributed import DaskRunner, connect

    with multiprocessing.get_context("spawn").Pool(1) as pool:
        local = pool.apply(in_process, (args.device, args.small))
    record = {"environment": {**local["environment"], "distributed": distributed.__version__, "commit": args.commit or commit()},
              "workers": args.workers, "workloads": {}}
    for name, run in local["runs"].items():
        record["workloads"][name] = {"spec": run["spec"], "in_process_s": run["wall_s"]}
    for workers in sorted({1, args.workers}):
        t0 = time.perf_counter()
        with connect(workers=workers, device=args.device) as client:
            client.wait_for_workers(workers)
            started = time.perf_counter() - t0
            runner = DaskRunner(client)
            for name, run in local["runs"].items():
                spec = EnsembleSpec.from_dict(run["spec"])
                entry = record["workloads"][name]
                warm = warm_up(spec, lambda s: DaskRunner(client, unit_size=1).run_specs([s], device=args.device))
                t1 = time.perf_counter()
                with distributed.get_task_stream(client) as stream, phase_clock(runner) as phases:
                    (result,) = runner.run_specs([spec], device=args.device)
                entry[f"workers_{workers}_s"] = time.perf_counter() - t1
                entry[f"workers_{workers}_phases"] = {**phases, **task_summary(stream.data, t1)}
                entry[f"workers_{workers}_max_rel_difference"] = largest_difference(result, run["spectra"])
                entry[f"workers_{workers}_start_s"], entry[f"workers_{workers}_warm_up_s"] = started, warm
                print(f"{name}: {workers} worker(s) {entry[f'workers_{workers}_s']:.3f} s, largest relative "
                      f"difference {entry[f'workers_{workers}_max_rel_difference']:.1e}", flush=True)
    for entry in record["workloads"].values():
        many = entry[f"workers_{args.workers}_s"]
        entry["max_rel_difference"] = max(entry[f"workers_{w}_max_rel_difference"] for w in {1, args.workers})
        entry["speedup"] = entry["in_process_s"] / many
        entry["one_worker_over_in_process"] = entry["workers_1_s"] / entry["in_process_s"]
        print(f"{entry['spec']['realizations']} x {entry['spec']['mode']}: {args.workers} workers "
              f"{entry['speedup']:.2f}x in process; 1 worker {entry['one_worker_over_in_process']:.3f} of it")
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
