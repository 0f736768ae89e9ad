"""Force-kernel timing at thesis scale (issue 2's performance targets), with correctness checks.

    python benchmarks/force_study.py --device cuda --realizations 300 --log2n 20 --out DIR

Times, per algorithm: rough-line generation, the per-line build (bounds, prefix sums, tree) and
the force launch alone, each the median of ``--repeats`` runs after a warm-up (compilation timed
apart), the device synchronized before every clock read. Checks tree == direct (max |dF|) on the
same lines, and writes ``force_study.json`` with device, versions and date.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import mdroll  # noqa: E402
from mdroll.devices import resolve_device, synchronize, warp  # noqa: E402
from mdroll.ensemble.force import launch_force, prepare_lines  # noqa: E402
from mdroll.provenance import environment  # noqa: E402


def timed(fn, device, repeats):
    """Median and all wall times (s) of ``fn()``, synchronizing the device around each call."""
    times = []
    result = None
    for _ in range(repeats):
        synchronize(device)
        t0 = time.perf_counter()
        result = fn()
        synchronize(device)
        times.append(time.perf_counter() - t0)
    return statistics.median(times), times, result


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--device", default="auto")
    parser.add_argument("--realizations", type=int, default=300)
    parser.add_argument("--log2n", type=int, default=20)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--algorithms", default="edge,tree,direct")
    parser.add_argument("--leaf-sizes", default="8")
    parser.add_argument("--boundary", default="open")
    parser.add_argument("--out", default="benchmarks/results")
    args = parser.parse_args(argv)

    device = resolve_device(args.device)
    wp = warp()
    params = mdroll.Params(L=(2**args.log2n) * 5e-6)
    R = args.realizations
    record = {"info": environment(device), "realizations": R, "n_points": params.n_points, "boundary": args.boundary,
              "results": []}

    # compilation and first launches, timed apart on a tiny problem
    small = mdroll.Params(L=0.05)
    t0 = time.perf_counter()
    tiny = mdroll.rough_lines(small, 0, 2, device=device)
    for algorithm in ("edge", "tree", "direct"):
        mdroll.contact_force(tiny, small, algorithm, args.boundary, device=device)
    synchronize(device)
    record["compile_and_first_launch_s"] = time.perf_counter() - t0

    gen_median, gen_times, lines = timed(lambda: mdroll.rough_lines(params, 1, R, device=device), device, args.repeats)
    record["generate_s"] = gen_median
    print(f"{environment(device)['device_name']}: {R} x {params.n_points} points; generate {gen_median * 1e3:.2f} ms", flush=True)

    d = params.d0
    forces = {}
    for algorithm in args.algorithms.split(","):
        for leaf in ([int(x) for x in args.leaf_sizes.split(",")] if algorithm == "tree" else [None]):
            kwargs = {"leaf_size": leaf} if leaf else {}
            build_median, _, prepared = timed(
                lambda: prepare_lines(lines, params, algorithm, args.boundary, d, device, **kwargs), device, args.repeats
            )
            repeats = args.repeats if algorithm != "direct" else max(2, args.repeats // 2)
            out = wp.empty((R, prepared.steps), dtype=wp.float64, device=device)
            force_median, force_times, force = timed(
                lambda: launch_force(prepared, params, algorithm, d, device, out=out), device, repeats
            )
            force = wp.clone(force)
            steps = prepared.steps
            entry = {
                "algorithm": algorithm,
                "leaf_size": leaf,
                "steps": steps,
                "build_s": build_median,
                "force_s": force_median,
                "force_times_s": force_times,
                "ns_per_step": force_median / (R * steps) * 1e9,
            }
            forces[(algorithm, leaf)] = force
            record["results"].append(entry)
            print(f"{algorithm:>6} leaf={leaf!s:>4}: build {build_median * 1e3:9.2f} ms  force {force_median * 1e3:9.2f} ms  "
                  f"({entry['ns_per_step']:.3f} ns/step)", flush=True)
            del prepared

    if ("direct", None) in forces:
        direct = forces[("direct", None)].numpy()
        for (algorithm, leaf), force in forces.items():
            diff = float(np.max(np.abs(force.numpy() - direct)))
            record.setdefault("max_abs_diff_vs_direct_N", {})[f"{algorithm}/{leaf}"] = diff
            print(f"max |F_{algorithm}(leaf={leaf}) - F_direct| = {diff:.3e} N ({diff / params.F_N:.2e} F_N)")

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    name = f"force_study_{device.replace(':', '')}_{R}x2e{args.log2n}.json"
    (out / name).write_text(json.dumps(record, indent=2))
    print(f"wrote {out / name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
