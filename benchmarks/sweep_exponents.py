"""The sweep's scaling on one device in its default form: force-only time against n under
refinement (fixed L) and under rolling distance (fixed dx), with the exponents of
``time ~ n^p`` fitted as ``mdroll bench --full`` does, at the sizes of its sections for that
device (``mdroll.bench.study.SIZES``; periodic lines, as there), for the sweep alone: about a
minute. On CUDA each section is timed twice: on the device's clock, as the study does
(``mdroll.bench.clocks.device_timed``), and on the wall clock around the launch.

    python benchmarks/sweep_exponents.py --device cpu --out cpu_sweep_exponents.json
    python benchmarks/sweep_exponents.py --device cuda --out cuda_sweep_exponents.json

``--realizations N`` replaces the study's lines a size (the CPU's study uses 1).
"""

import argparse
import json

import numpy as np

from mdroll import Params
from mdroll.bench.study import SIZES, fit_exponent, force_time
from mdroll.devices import resolve_device
from mdroll.provenance import environment


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--out", default="sweep_exponents.json")
    parser.add_argument("--repeats", type=int, default=SIZES["full"].repeats)
    parser.add_argument("--realizations", type=int, default=None)
    args = parser.parse_args()
    device = resolve_device(args.device)
    study = SIZES["full"]
    record = {"environment": environment(device), "algorithm": "sweep", "sections": {}}
    # CUDA: the study's device clock, and the wall clock around the launch beside it
    clocks = ("device", "wall") if device.startswith("cuda") else ("device",)
    for section, (sizes, _) in study.sweeps(device).items():
        realizations = args.realizations or study.realizations(device, section, "sweep")
        for clock in clocks:
            points = [force_time(p, "sweep", realizations, device, args.repeats, clock=clock) for p in sizes]
            p, err = fit_exponent(np.array([q["n"] for q in points]), np.array([q["force_s"] for q in points]))
            name = section if clock == "device" else f"{section} (wall clock)"
            record["sections"][name] = {"points": points, "exponent": p, "exponent_stderr": err}
            print(f"{name:25s} p = {p:.3f} +- {err:.3f}  ("
                  + ", ".join(f"{q['n']}: {q['ns_per_step']:.4f} ns/step" for q in points) + ")", flush=True)
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
