"""Where one worker's fixed cost goes: one unit of a decoupled run on a local cluster of one
worker, stamped on the host's clock (worker and client share it) at the call, the worker count's
query, the submit, the unit's start and its run's end on the worker, its part's end, the client's
notice of the finished unit, the part's arrival and the result.

    python benchmarks/unit_latency.py --device cuda:0 --out unit_latency.json

Three variants of the same runs: back to back (each submitted as the last returns), each from an
idle cluster (``--idle`` seconds after the last), and back to back with Dask's batched-send
intervals at zero on the client, the scheduler and the worker (Dask's internals, set here for
the measurement only: the client sends its messages at least 10 ms apart, the scheduler 5 ms,
a worker 2 ms). Dask is imported in ``main`` only.
"""

import argparse
import dataclasses
import json
import time

VARIANTS = ("back-to-back", "idle", "no-batching")


def timed_unit(spec, device):
    """The worker's task: the unit's part and the stamps of its start, its run's end and its
    part's end."""
    from mdroll.distributed.parts import part_of

    started = time.time()
    result = spec.run(device=device, progress=False)
    ran = time.time()
    part = part_of(result, spec.first)
    return part, (started, ran, time.time(), result.batch)


def stamps_of_one_run(client, spec, device: str, key: str) -> dict:
    """One unit through the client as :class:`mdroll.distributed.DaskRunner` sends it: the
    milliseconds of each step."""
    from distributed import as_completed

    from mdroll.distributed.parts import result_of

    called = time.time()
    client.scheduler_info()
    asked = time.time()
    future = client.submit(timed_unit, spec, device, key=key)
    submitted = time.time()
    for done in as_completed([future]):
        noticed = time.time()
        part, (started, ran, parted, batch) = done.result()
        gathered = time.time()
    result_of(part)
    returned = time.time()
    steps = {"workers_query": asked - called, "submit": submitted - asked, "to_unit_start": started - submitted,
             "unit_run": ran - started, "part_of": parted - ran, "to_notice": noticed - parted,
             "part_transfer": gathered - noticed, "result_of": returned - gathered, "total": returned - called}
    return {**{k: v * 1e3 for k, v in steps.items()}, "batch": batch}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--length", type=float, default=5.24288, help="L (m): 2^20 springs of 5 um by default")
    parser.add_argument("--realizations", type=int, default=6000)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--idle", type=float, default=0.2, help="seconds before each run of the idle variant")
    parser.add_argument("--commit", default="unknown")
    parser.add_argument("--out", default="unit_latency.json")
    args = parser.parse_args()
    import distributed

    from mdroll import EnsembleSpec, Params
    from mdroll.distributed import connect
    from mdroll.provenance import environment

    spec = EnsembleSpec(Params(L=args.length), seed=0, realizations=args.realizations, mode="decoupled")
    provenance = {**environment(args.device), "distributed": distributed.__version__, "commit": args.commit}
    record = {"environment": provenance, "spec": spec.as_dict(), "units": "ms", "runs": {}}
    with connect(workers=1, device=args.device) as client:
        client.wait_for_workers(1)
        for warm in (dataclasses.replace(spec, params=Params(L=0.05), realizations=8), spec):
            client.submit(timed_unit, warm, args.device, pure=False).result()
        for variant in VARIANTS:
            if variant == "no-batching":
                client.scheduler_comm.interval = 0.0
                scheduler = client.cluster.scheduler
                for comm in [*scheduler.stream_comms.values(), *scheduler.client_comms.values()]:
                    comm.interval = 0.0
                client.run(lambda dask_worker: setattr(dask_worker.batched_stream, "interval", 0.0))
            runs = []
            for i in range(args.repeat):
                if variant == "idle":
                    time.sleep(args.idle)
                runs.append(stamps_of_one_run(client, spec, args.device, f"unit-{variant}-{i}"))
                print(variant, {k: round(v, 1) for k, v in runs[-1].items()}, flush=True)
            record["runs"][variant] = runs
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
