"""Coupled mode (eq 13) at thesis scale (300 x 2^20, open boundary): the wall time of one warm
:func:`mdroll.run_ensemble` call per algorithm with a coupled step, after a small warm-up run of
each (its kernels compiled or loaded), with the pipeline's stage timings; and how far each exact
algorithm's force spectrum lies from the tree's. ``--more`` adds runs of more realizations
(``more_realizations``: wall time per count and algorithm); each run with the realizations its
largest batch held (``batch``).

    python benchmarks/coupled_thesis.py --device cuda:0 --more 1200 --out coupled_thesis.json
"""

import argparse
import json
import time

import numpy as np

from mdroll import Params, run_ensemble
from mdroll.devices import resolve_device, synchronize
from mdroll.forces.registry import REGISTRY
from mdroll.provenance import environment


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--out", default="coupled_thesis.json")
    parser.add_argument("--more", type=int, nargs="*", default=[], help="further realization counts")
    args = parser.parse_args()
    device = resolve_device(args.device)
    p = Params(L=5.24288)
    record = {"environment": environment(device), "params": p.as_dict(), "realizations": 300, "runs": {},
              "more_realizations": {}}
    spectra = {}
    for entry in REGISTRY.values():
        if entry.coupled is None:
            continue
        run_ensemble(Params(L=0.05), realizations=4, algorithm=entry.name, mode="coupled", device=device,
                     progress=False)
        for count in [300, *args.more]:
            synchronize(device)
            start = time.perf_counter()
            result = run_ensemble(p, realizations=count, algorithm=entry.name, mode="coupled", device=device,
                                  progress=False)
            wall = time.perf_counter() - start
            print(f"{entry.name:<7} {count:5d} {wall:8.3f} s (batch {result.batch})", flush=True)
            run = {"wall_s": wall, "batch": result.batch, "timings": result.timings}
            if count != 300:
                record["more_realizations"].setdefault(str(count), {})[entry.name] = run
                continue
            spectra[entry.name] = result.force_psd
            record["runs"][entry.name] = run
    for name, psd in spectra.items():
        if REGISTRY[name].exact:
            gap = float(np.max(np.abs(psd - spectra["tree"])) / np.max(spectra["tree"]))
            record["runs"][name]["force_psd_from_tree"] = gap
            print(f"{name:<7} force PSD from the tree's: {gap:.1e} of its largest bin")
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
