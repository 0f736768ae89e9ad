"""Tree tuning on one device: leaf size x band chunk at thesis scale (300 x 2^20, open), and the
refinement exponent (``mdroll bench --full``'s sweep) per setting.

    python benchmarks/tree_tuning.py --device cuda:0 --out tree_tuning.json

Each point is ``mdroll.bench.force_time``: median of repeats on fresh lines, device synchronized.
``chunk_blocks`` 0 sums every band whole (the kernel before chunking); ``descent`` is the shared
8-step traversal of every band (band_limit 0, leaf 8; ``tree-descent`` in ``mdroll bench``). The
defaults in ``mdroll/ensemble/force.py`` (DEFAULT_LEAF_SIZE, DEFAULT_CHUNK_BLOCKS,
DEFAULT_BAND_LIMIT) come from this study; benchmarks/NOTES.md records its numbers.
"""

import argparse
import json

from mdroll import Params
from mdroll.bench import STUDIES, TREE_DESCENT, fit_exponent, force_time
from mdroll.devices import resolve_device
from mdroll.ensemble.force import DEFAULT_BAND_LIMIT
from mdroll.provenance import environment

#: (label, leaf_size, band_limit, chunk_blocks)
SETTINGS = [(f"leaf {leaf} chunk {chunk}", leaf, DEFAULT_BAND_LIMIT, chunk)
            for leaf in (16, 32) for chunk in (0, 1, 2, 4, 8)]
SETTINGS.append(("descent", TREE_DESCENT["leaf_size"], TREE_DESCENT["band_limit"], 0))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--thesis", action=argparse.BooleanOptionalAction, default=True,
                        help="time the thesis-scale point of each setting")
    parser.add_argument("--out", default="tree_tuning.json")
    args = parser.parse_args()
    device = resolve_device(args.device)
    thesis = Params(L=5.24288, n_real=300)
    record = {"environment": environment(device), "thesis": [], "refinement": [], "fits": {}}
    sizes, realizations = STUDIES["full"].sweeps(device)["refinement"]
    for label, leaf_size, band_limit, chunk_blocks in SETTINGS:
        if args.thesis:
            point = force_time(thesis, "tree", thesis.n_real, device, args.repeats, "open", leaf_size, band_limit,
                               chunk_blocks)
            record["thesis"].append(point)
            print(f"thesis {label:>20}: {point['force_s'] * 1e3:7.2f} ms", flush=True)
        points = [force_time(p, "tree", realizations, device, args.repeats, "periodic", leaf_size, band_limit, chunk_blocks)
                  for p in sizes]
        record["refinement"] += points
        slope, err = fit_exponent([p["n"] for p in points], [p["force_s"] for p in points])
        record["fits"][label] = {"exponent": slope, "stderr": err}
        times = " ".join(f"{p['force_s'] * 1e3:.2f}" for p in points)
        print(f"refinement {label:>20}: n^{slope:.3f} +- {err:.3f}  ({times} ms)", flush=True)
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
