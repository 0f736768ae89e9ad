"""The boundary-element solver on Hertz's sphere under refinement: the relative errors of force,
approach, contact radius, peak pressure and pressure profile at 32 .. 512 cells across the contact
diameter, and the observed order between successive grids; JSON to --out (docs/bem.md).

    python benchmarks/bem_hertz.py --out benchmarks/results/bem_hertz.json [--cells 32 64 128 256 512]
"""

import argparse
import json
import math
import time

from mdroll import physics
from mdroll.bem.hertz import sphere_errors
from mdroll.provenance import environment


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, nargs="+", default=[32, 64, 128, 256, 512])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--out", required=True)
    args = parser.parse_args(argv)
    E_star, R, d = physics.effective_modulus(210e9, 0.3), 0.5, 20e-6
    rows = []
    for cells in args.cells:
        start = time.perf_counter()
        errors = sphere_errors(cells, E_star, R, d, args.device)
        rows.append({"cells": cells, "seconds": time.perf_counter() - start, **errors})
        print(json.dumps(rows[-1]), flush=True)
    for coarse, fine in zip(rows, rows[1:]):
        fine["order"] = {name: math.log(abs(coarse[name]) / abs(fine[name])) / math.log(fine["cells"] / coarse["cells"])
                         for name in ("force", "approach", "radius", "max_pressure", "profile")}
    record = {"problem": {"E_star": E_star, "R": R, "approach": d, "grid": "1.25 x the contact diameter"},
              "environment": environment(args.device), "rows": rows}
    with open(args.out, "w") as out:
        json.dump(record, out, indent=1)


if __name__ == "__main__":
    main()
