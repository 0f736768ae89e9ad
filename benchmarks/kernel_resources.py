"""How many registers and how much local memory (spills, stacks) do mdroll's CUDA kernels take?
The question behind the tree kernel's cap of 128 registers: at 255 registers it ran 8 warps a
multiprocessor (docs/performance.md, v8).

    python benchmarks/kernel_resources.py [--match tree] [--out resources.json]

Runs each force algorithm once on a small CUDA problem so that Warp compiles its modules, then
loads every cubin/PTX in Warp's kernel cache whose name contains ``--match`` with CuPy and prints
``num_regs`` and ``local_size_bytes`` per kernel (no profiler is installed on the GPU machine).
"""

import argparse
import glob
import json
import os
import re

import cupy
import warp as wp

from mdroll import ALGORITHMS, Params, contact_force
from mdroll.ensemble.lines import rough_lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--match", default="kernels")
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    p = Params(L=0.04, dx=10e-6)
    lines = rough_lines(p, 1, 4, "cuda:0")
    for algorithm in ALGORITHMS:
        contact_force(lines, p, algorithm, "periodic", device="cuda:0")
    wp.synchronize()
    record = {}
    for path in sorted(glob.glob(os.path.join(wp.config.kernel_cache_dir, f"*{args.match}*", "*"))):
        if not path.endswith((".cubin", ".ptx")):
            continue
        source = glob.glob(os.path.join(os.path.dirname(path), "*.cu"))
        names = set()
        for cu in source:
            names |= set(re.findall(r'extern "C" __global__ void (?:WP_MAXNREG\(\d+\) )?(\w+)\(', open(cu).read()))
        module = cupy.RawModule(path=path)
        for name in sorted(names):
            if not name.endswith("forward"):
                continue
            attributes = module.get_function(name).attributes
            record[f"{os.path.basename(path)}:{name}"] = {
                "num_regs": attributes["num_regs"], "local_size_bytes": attributes["local_size_bytes"]}
            print(f"{os.path.basename(path)} {name}: {attributes['num_regs']} registers, "
                  f"{attributes['local_size_bytes']} B local", flush=True)
    if args.out:
        with open(args.out, "w") as f:
            json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
