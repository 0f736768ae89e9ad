"""Tree tuning on one device: leaf size x band_limit at thesis scale (300 x 2^20, open), and
the refinement exponent (``mdroll bench --full``'s sweep) per band_limit.

    python benchmarks/tree_tuning.py --device cuda:0 --out tree_tuning.json

Each point is ``mdroll.bench.force_time``: median of repeats on fresh lines, device synchronized.
The defaults in ``mdroll/forces/prepared.py`` (DEFAULT_LEAF_SIZE, DEFAULT_BAND_LIMIT) come from
this study; docs/performance.md records its numbers.
"""

import argparse
import json

from mdroll import Params
from mdroll.bench import SIZES, fit_exponent, force_time
from mdroll.devices import resolve_device
from mdroll.provenance import environment

LEAF_SIZES = (8, 16, 32)
BAND_LIMITS = (0, 1024, 2048, 4096, 10**6)  # springs a side, row-wide; 0: always traverse, 10^6: always sum directly
REFINEMENT_LEAF_SIZES = (8, 32)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--out", default="tree_tuning.json")
    parser.add_argument("--leaf-sizes", type=int, nargs="+", default=LEAF_SIZES, help="thesis-scale leaf sizes")
    parser.add_argument("--band-limits", type=int, nargs="+", default=BAND_LIMITS, help="band limits (springs)")
    parser.add_argument("--refinement-leaf-sizes", type=int, nargs="+", default=REFINEMENT_LEAF_SIZES)
    args = parser.parse_args()
    device = resolve_device(args.device)
    thesis, count = Params(L=5.24288), 300
    record = {"environment": environment(device), "thesis": [], "refinement": [], "fits": {}}
    for leaf_size in args.leaf_sizes:
        for band_limit in args.band_limits:
            point = force_time(thesis, "tree", count, device, args.repeats, "open", leaf_size, band_limit)
            record["thesis"].append(point)
            print(f"thesis leaf {leaf_size:>2} band_limit {band_limit:>7}: {point['force_s'] * 1e3:7.2f} ms", flush=True)
    sizes, realizations = SIZES["full"].sweeps(device)["refinement"]
    for leaf_size in args.refinement_leaf_sizes:
        for band_limit in args.band_limits:
            points = [force_time(p, "tree", realizations, device, args.repeats, "periodic", leaf_size, band_limit)
                      for p in sizes]
            record["refinement"] += points
            slope, err = fit_exponent([p["n"] for p in points], [p["force_s"] for p in points])
            record["fits"][f"leaf {leaf_size} band_limit {band_limit}"] = {"exponent": slope, "stderr": err}
            times = " ".join(f"{p['force_s'] * 1e3:.2f}" for p in points)
            print(f"refinement leaf {leaf_size:>2} band_limit {band_limit:>7}: n^{slope:.3f} +- {err:.3f}  ({times} ms)",
                  flush=True)
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
