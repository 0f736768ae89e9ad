"""Coupled mode (eq 13) at thesis scale (300 x 2^20, open boundary): the wall time of one warm
:func:`mdroll.run_ensemble` call per algorithm with a coupled step, after a small warm-up run of
each (its kernels compiled or loaded), with the pipeline's stage timings; and how far each exact
algorithm's force spectrum lies from the tree's.

    python benchmarks/coupled_thesis.py --device cuda:0 --out coupled_thesis.json
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
    args = parser.parse_args()
    device = resolve_device(args.device)
    p, count = Params(L=5.24288), 300
    record = {"environment": environment(device), "params": p.as_dict(), "realizations": count, "runs": {}}
    spectra = {}
    for entry in REGISTRY.values():
        if entry.coupled is None:
            continue
        run_ensemble(Params(L=0.05), realizations=4, algorithm=entry.name, mode="coupled", device=device, progress=False)
        synchronize(device)
        start = time.perf_counter()
        result = run_ensemble(p, realizations=count, algorithm=entry.name, mode="coupled", device=device, progress=False)
        wall = time.perf_counter() - start
        spectra[entry.name] = result.force_psd
        record["runs"][entry.name] = {"wall_s": wall, "timings": result.timings}
        print(f"{entry.name:<7} {wall:8.3f} s", flush=True)
    for name, psd in spectra.items():
        if REGISTRY[name].exact:
            gap = float(np.max(np.abs(psd - spectra["tree"])) / np.max(spectra["tree"]))
            record["runs"][name]["force_psd_from_tree"] = gap
            print(f"{name:<7} force PSD from the tree's: {gap:.1e} of its largest bin")
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
