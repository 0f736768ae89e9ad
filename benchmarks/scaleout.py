"""Scale-out of the Dask runner (mdroll.distributed) against one GPU in a process of its own:
per workload, the warm wall time in process, on a local cluster of one worker and of two (one
per GPU, pinned), and the largest relative difference of the cluster's spectra from the
in-process run's.

    python benchmarks/scaleout.py --device cuda:0 --out scaleout.json

Workloads at thesis scale (2^20 springs, open boundary, the mode's default algorithm): the
decoupled sweep of 6000 realizations, the coupled run of 1200, and runs of each mode sized to take
about one and five seconds in process (from that mode's first workload's rate, then rescaled once
by their own time in process). The in-process run goes in a
spawned child that exits before any cluster starts, so that no GPU memory of this process
shrinks a worker's batches. In process and on each cluster alike, every workload is timed
``--repeat`` times after the same small warm-up of its kernels (and, for the workloads sized in
seconds, one untimed run at their size: the in-process one that rescales them), each from an idle
process or cluster (``IDLE_S`` after the last), and its time is the median (all are recorded; the
clusters' start-up and warm-up beside). ``--small`` runs the same at a size
for the CPU (``--device cpu``: worker processes of one core each). Each cluster run also records
where its time went, on the host's clock: from the call to the first unit's start, the units'
span, from the last unit's end to the result (the transfers of the parts and their merge), and
per task kind (unit, merge) the workers' compute and transfer seconds (Dask's task stream). Dask
is imported in ``main`` only.
"""

import argparse
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
#: take about their seconds in process, then rescaled once by their own time (:func:`calibrated`;
#: the targets are stated at one and at five seconds).
WORKLOADS = (("decoupled-6000", "decoupled", 6000), ("coupled-1200", "coupled", 1200),
             ("decoupled-1s", "decoupled", 1.0), ("decoupled-5s", "decoupled", 5.0),
             ("coupled-1s", "coupled", 1.0), ("coupled-5s", "coupled", 5.0))
THESIS_L = 5.24288  # m: 2^20 springs of 5 um
#: Seconds between timed runs: a run starts on an idle cluster, as a user's does. Dask's client
#: sends its messages at least 10 ms apart, so a run submitted within 10 ms of the last one's
#: release of its parts (sent as that run returns) would wait for it, which no single run does.
IDLE_S = 0.05
SMALL = {"L": 0.1, "decoupled": 48, "coupled": 16}
WARM_UP_L = 0.05


def sized(spec, name: str, rates: dict, small: bool):
    """The workload ``name``'s spec: its own count, or its seconds at its mode's measured rate."""
    mode, amount = next((m, a) for n, m, a in WORKLOADS if n == name)
    if isinstance(amount, int):
        return dataclasses.replace(spec, realizations=SMALL[mode] if small else amount)
    count = max(2, int(round(rates[mode] * amount, 0 if small else -1)))
    return dataclasses.replace(spec, realizations=count)


def calibrated(spec, name: str, run, small: bool):
    """A workload counted in seconds, its count rescaled once by its own time in process (a
    mode's rate at its first workload's size does not hold at every size: a coupled batch takes
    nearly its full time whatever its realizations)."""
    amount = next(a for n, _, a in WORKLOADS if n == name)
    if isinstance(amount, int):
        return spec
    t0 = time.perf_counter()
    run([spec])
    count = spec.realizations * amount / (time.perf_counter() - t0)
    return dataclasses.replace(spec, realizations=max(2, int(round(count, 0 if small else -1))))


def specs_for(small: bool, only=None):
    """The workloads' specs (their counts set later), all or those named in ``only`` with the
    first of each of their modes, which gives the mode's rate."""
    from mdroll import EnsembleSpec, Params

    L = SMALL["L"] if small else THESIS_L
    modes = {mode for name, mode, _ in WORKLOADS if only is None or name in only}
    firsts = {next(name for name, m, _ in WORKLOADS if m == mode) for mode in modes}
    return {name: EnsembleSpec(Params(L=L), seed=0, realizations=1, mode=mode) for name, mode, _ in WORKLOADS
            if only is None or name in only or name in firsts}


def median_run(seconds: list) -> int:
    """The index of the median of ``seconds`` (the upper of the two middle ones for an even count)."""
    return int(np.argsort(seconds)[len(seconds) // 2])


def timed(spec, run, repeat: int) -> tuple[list[float], object]:
    """``run([spec])`` ``repeat`` times: the seconds of each, and the last result."""
    seconds = []
    for _ in range(repeat):
        time.sleep(IDLE_S)
        t0 = time.perf_counter()
        (result,) = run([spec])
        seconds.append(time.perf_counter() - t0)
    return seconds, result


def warm_up(spec, run) -> float:
    """Run a short copy of ``spec`` (its kernels loaded, its FFTs planned); its seconds."""
    from mdroll import Params

    t0 = time.perf_counter()
    run(dataclasses.replace(spec, params=Params(L=WARM_UP_L), realizations=8))
    return time.perf_counter() - t0


def in_process(device: str, small: bool, repeat: int, only=None) -> dict:
    """In a spawned child: each workload's warm wall times and spectra on ``device`` (the sized
    ones from their mode's first workload's rate, :func:`sized`), and the environment."""
    from mdroll import run_specs
    from mdroll.provenance import environment

    out = {"environment": environment(device), "runs": {}}
    rates = {}
    for name, spec in specs_for(small, only).items():
        spec = sized(spec, name, rates, small)
        warm_up(spec, lambda s: run_specs([s], device=device))
        spec = calibrated(spec, name, lambda s: run_specs(s, device=device), small)
        seconds, result = timed(spec, lambda s: run_specs(s, device=device), repeat)
        out["runs"][name] = {"wall_s": seconds[median_run(seconds)], "runs_s": seconds, "spec": spec.as_dict(),
                             "spectra": {f: getattr(result, f) for f in FIELDS}}
        rates.setdefault(spec.mode, spec.realizations / out["runs"][name]["wall_s"])
        print(f"{name}: in process {out['runs'][name]['wall_s']:.3f} s ({' '.join(f'{t:.3f}' for t in seconds)})", flush=True)
    return out


def largest_difference(result, reference: dict) -> float:
    return max(float(np.max(np.abs(getattr(result, f) - reference[f])) / np.max(np.abs(reference[f]))) for f in FIELDS)


def phases(tasks: list, called: float, returned: float) -> dict:
    """Where a cluster run's time went, on the host clock (``called`` and ``returned``: the
    call's start and end, ``time.time``, the task stream's clock): seconds from the call to the
    first unit's start, the units' span (first start to last end), from the last unit's end to
    the result (the parts' merges and transfers not overlapped with the units, and the client's
    merge); and per task kind (the key's second word: unit, merge) the tasks' count and their
    compute and transfer seconds summed."""
    kinds = {}
    for t in tasks:
        kind = str(t["key"]).split("-")[1] if "-" in str(t["key"]) else "other"
        entry = kinds.setdefault(kind, {"count": 0, "compute_s": 0.0, "transfer_s": 0.0})
        entry["count"] += 1
        for s in t["startstops"]:
            entry[f"{s['action']}_s"] = entry.get(f"{s['action']}_s", 0.0) + s["stop"] - s["start"]
    units = [s for t in tasks if str(t["key"]).startswith("mdroll-unit") for s in t["startstops"]
             if s["action"] == "compute"]
    if not units:  # the task stream missed them: the kinds alone
        return {"tasks": kinds}
    first, last = min(s["start"] for s in units), max(s["stop"] for s in units)
    ends = sorted(s["stop"] for s in units)
    return {"to_first_unit_s": first - called, "units_span_s": last - first, "after_units_s": returned - last,
            "units_end_spread_s": ends[-1] - ends[0], "tasks": kinds}


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
    parser.add_argument("--repeat", type=int, default=3, help="timed runs of each workload, each place (median)")
    parser.add_argument("--only", nargs="+", choices=[name for name, _, _ in WORKLOADS],
                        help="these workloads only (with the first of each of their modes)")
    parser.add_argument("--commit", help="the commit measured (default: git rev-parse HEAD, where there is a .git)")
    parser.add_argument("--out", default="scaleout.json")
    args = parser.parse_args()
    import distributed  # imported here: the clusters' machine may carry Dask apart from the package

    from mdroll import EnsembleSpec
    from mdroll.distributed import DaskRunner, connect

    with multiprocessing.get_context("spawn").Pool(1) as pool:
        local = pool.apply(in_process, (args.device, args.small, args.repeat, args.only))
    record = {"environment": {**local["environment"], "distributed": distributed.__version__, "commit": args.commit or commit()},
              "workers": args.workers, "repeat": args.repeat, "workloads": {}}
    for name, run in local["runs"].items():
        record["workloads"][name] = {"spec": run["spec"], "in_process_s": run["wall_s"], "in_process_runs_s": run["runs_s"]}
    write(args.out, record)
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
                if isinstance(next(a for n, _, a in WORKLOADS if n == name), float):
                    runner.run_specs([spec], device=args.device)  # untimed, as the in-process calibration run
                seconds, found = [], []
                for _ in range(args.repeat):
                    time.sleep(IDLE_S)
                    with distributed.get_task_stream(client) as stream:
                        called = time.time()
                        t1 = time.perf_counter()
                        (result,) = runner.run_specs([spec], device=args.device)
                        seconds.append(time.perf_counter() - t1)
                        returned = time.time()
                    found.append(phases(stream.data, called, returned))
                middle = median_run(seconds)
                entry[f"workers_{workers}_s"], entry[f"workers_{workers}_runs_s"] = seconds[middle], seconds
                entry[f"workers_{workers}_phases"], entry[f"workers_{workers}_phases_runs"] = found[middle], found
                entry[f"workers_{workers}_max_rel_difference"] = largest_difference(result, run["spectra"])
                entry[f"workers_{workers}_start_s"], entry[f"workers_{workers}_warm_up_s"] = started, warm
                print(f"{name}: {workers} worker(s) {entry[f'workers_{workers}_s']:.3f} s "
                      f"({' '.join(f'{t:.3f}' for t in seconds)}), largest relative difference "
                      f"{entry[f'workers_{workers}_max_rel_difference']:.1e}; "
                      + ", ".join(f"{k} {v:.3f}" for k, v in found[middle].items() if k != "tasks"), flush=True)
                write(args.out, record)  # what is measured so far, should a later step fail
    for entry in record["workloads"].values():
        many = entry[f"workers_{args.workers}_s"]
        entry["max_rel_difference"] = max(entry[f"workers_{w}_max_rel_difference"] for w in {1, args.workers})
        entry["speedup"] = entry["in_process_s"] / many
        entry["one_worker_over_in_process"] = entry["workers_1_s"] / entry["in_process_s"]
        print(f"{entry['spec']['realizations']} x {entry['spec']['mode']}: {args.workers} workers "
              f"{entry['speedup']:.2f}x in process; 1 worker {entry['one_worker_over_in_process']:.3f} of it")
    write(args.out, record)


def write(path: str, record: dict) -> None:
    with open(path, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
