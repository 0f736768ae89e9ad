"""Warm end-to-end decoupled runs at thesis scale (300 x 2^20, open boundary) per algorithm:
median of 3 after a warm-up run, with the pipeline's own stage timings.

    python benchmarks/e2e_thesis.py --device cuda:0 --out e2e.json
    python benchmarks/e2e_thesis.py --algorithm edge --algorithm tree   # these, in this order

An algorithm named twice is measured twice (``end_to_end`` keeps the last; ``runs`` has all, in
order), to see whether a figure depends on what ran before it in the process.
"""

import argparse
import json

from mdroll import Params, run_ensemble
from mdroll.bench import timed
from mdroll.devices import resolve_device
from mdroll.forces.registry import ALGORITHMS
from mdroll.provenance import environment


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--out", default="e2e.json")
    parser.add_argument("--algorithm", action="append", choices=ALGORITHMS,
                        help="measure this algorithm (repeatable, in order; default: every one, registry order)")
    args = parser.parse_args()
    device = resolve_device(args.device)
    p, count = Params(L=5.24288), 300
    record = {"environment": environment(device), "params": p.as_dict(), "realizations": count, "end_to_end": {},
              "runs": []}
    for algorithm in args.algorithm or ALGORITHMS:
        def run():
            return run_ensemble(p, realizations=count, algorithm=algorithm, device=device, progress=False)

        run()
        total, times = timed(run, device, 3)
        stages = run().timings
        record["end_to_end"][algorithm] = {"total_s": total, "times_s": times, "stages_s": stages}
        record["runs"].append({"algorithm": algorithm, **record["end_to_end"][algorithm]})
        print(f"{algorithm:<7} {total * 1e3:8.1f} ms  " + "  ".join(f"{k} {v * 1e3:.1f}" for k, v in stages.items()))
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
