"""Sweep tuning on one device at thesis scale (300 x 2^20, open, d0): the force kernel alone for
tiles x lanes x loads (kernels/sweep.py), beside the edge and tree kernels and the device's copy
floor, and a check of every variant against the default.

    python benchmarks/sweep_tuning.py --device cuda:0 --out sweep_tuning.json

Each time is the median of ``--repeats`` launches on fresh lines on the device's clock
(``mdroll.bench.device_timed``, the launch recorded outside the clock). The floor is a
device-to-device copy of the lines (bytes read + written over its time): the sweep moves 16 bytes
a step (a height in, a force out), as the edge kernel does. The defaults in
``mdroll/ensemble/sweep.py`` (CUDA_MIN_TILE, CUDA_BLOCK_DIM, CUDA_LOADS) come from this study.
"""

import argparse
import itertools
import json

import numpy as np

from mdroll import Params, rough_lines
from mdroll.bench import device_timed, force_time
from mdroll.devices import resolve_device, to_warp, warp
from mdroll.ensemble.pipeline import H_BOUND_SIGMAS
from mdroll.ensemble.prepare import prepare_lines
from mdroll.ensemble.sweep import sweep_command
from mdroll.provenance import environment

TILES = (512, 1024, 2048)
LANES = (64, 128, 256)
LOADS = (1, 2, 4)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--out", default="sweep_tuning.json")
    parser.add_argument("--tiles", type=int, nargs="+", default=TILES)
    parser.add_argument("--lanes", type=int, nargs="+", default=LANES)
    parser.add_argument("--loads", type=int, nargs="+", default=LOADS)
    parser.add_argument("--length", type=float, default=5.24288, help="line length L (m); 5.24288: 2^20 springs")
    parser.add_argument("--realizations", type=int, default=300)
    args = parser.parse_args()
    wp = warp()
    device = resolve_device(args.device)
    p = Params(L=args.length, n_real=args.realizations)
    d = p.d0
    record = {"environment": environment(device), "params": p.as_dict(), "kernels": {}, "sweep": []}

    lines = to_warp(rough_lines(p, 0, p.n_real, device=device), device)
    copy = wp.empty_like(lines)
    copy_s, _ = device_timed(lambda: wp.copy(copy, lines), device, args.repeats)
    record["copy_floor"] = {"bytes": 2 * lines.size * 8, "s": copy_s, "bytes_per_s": 2 * lines.size * 8 / copy_s}
    print(f"copy floor: {2 * lines.size * 8 / copy_s / 1e12:.2f} TB/s ({copy_s * 1e3:.2f} ms for 2 x {lines.size * 8 / 1e9:.2f} GB)",
          flush=True)
    del copy

    for algorithm in ("edge", "tree", "sweep"):
        point = force_time(p, algorithm, p.n_real, device, args.repeats, "open")
        record["kernels"][algorithm] = point
        print(f"{algorithm:<6} force {point['force_s'] * 1e3:7.2f} ms  build {point['build_s'] * 1e3:6.2f} ms", flush=True)

    prepared = prepare_lines(lines, p, "sweep", "open", d, device, h_max=H_BOUND_SIGMAS * p.h0)
    default_command, default_force = sweep_command(prepared, p, d, device)
    default_command.launch()
    reference = default_force.numpy()
    for tile, lanes, loads in itertools.product(args.tiles, args.lanes, args.loads):
        if tile % lanes:
            continue
        command, force = sweep_command(prepared, p, d, device, tile_steps=tile, block_dim=lanes, loads=loads)
        command.launch()
        error = float(np.max(np.abs(force.numpy() - reference)) / p.F_N)
        seconds, times = device_timed(lambda: command.launch(), device, args.repeats)
        record["sweep"].append({"tile": tile, "lanes": lanes, "loads": loads, "force_s": seconds, "times_s": times,
                                "max_error_over_F_N": error})
        print(f"sweep tile {tile:>5} lanes {lanes:>4} loads {loads}: {seconds * 1e3:7.2f} ms  (|F - default| / F_N "
              f"{error:.1e})", flush=True)
    best = min(record["sweep"], key=lambda point: point["force_s"])
    print(f"best: tile {best['tile']} lanes {best['lanes']} loads {best['loads']} {best['force_s'] * 1e3:.2f} ms; "
          f"edge {record['kernels']['edge']['force_s'] * 1e3:.2f} ms")
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
