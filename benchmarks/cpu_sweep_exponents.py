"""The sweep's scaling on one CPU core (its sequential form, the CPU default): force-only time
against n under refinement (fixed L, n = 2^13..2^18) and under rolling distance (fixed dx,
n = 2^14..2^22), with the exponents of ``time ~ n^p`` fitted as ``mdroll bench --full`` does.

    python benchmarks/cpu_sweep_exponents.py --out cpu_sweep_exponents.json

The same sizes as the CPU sections of ``mdroll bench --full`` (``mdroll.bench.study.STUDIES``),
for the sweep alone, so that it runs in about a minute on an idle machine.
"""

import argparse
import json

import numpy as np

from mdroll import Params
from mdroll.bench.study import STUDIES, fit_exponent, force_time
from mdroll.provenance import environment


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="cpu_sweep_exponents.json")
    parser.add_argument("--repeats", type=int, default=STUDIES["full"].repeats)
    args = parser.parse_args()
    study = STUDIES["full"]
    record = {"environment": environment("cpu"), "algorithm": "sweep", "sections": {}}
    for section, (sizes, realizations) in study.sweeps("cpu").items():
        points = [force_time(p, "sweep", realizations, "cpu", args.repeats, "open") for p in sizes]
        p, err = fit_exponent(np.array([q["n"] for q in points]), np.array([q["force_s"] for q in points]))
        record["sections"][section] = {"points": points, "exponent": p, "exponent_stderr": err}
        print(f"{section:10s} p = {p:.3f} +- {err:.3f}  ("
              + ", ".join(f"{q['n']}: {q['ns_per_step']:.1f} ns/step" for q in points) + ")", flush=True)
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
