"""The sweep's stream form on one CUDA device: force kernel alone at thesis scale (300 x 2^20,
open, d0) in its default layout and in others (``STREAM_LAYOUTS`` in ``mdroll/forces/sweep.py``,
each with and without the delay line), beside the edge kernel and the sequential form, each
checked against the sequential form. The exponents: ``benchmarks/sweep_exponents.py``.

    python benchmarks/sweep_stream_tuning.py --out sweep_stream.json

Times: median of ``--repeats`` launches on the device's clock (``mdroll.bench.device_timed``,
launch recorded outside the clock), edge's as the study's (``mdroll.bench.force_time``).
"""

import argparse
import json

import numpy as np

import mdroll.forces.sweep as sweep
from mdroll import Params, rough_lines
from mdroll.bench import device_timed, force_time
from mdroll.devices import resolve_device, to_warp
from mdroll.ensemble.pipeline import H_BOUND_SIGMAS
from mdroll.forces.prepare import prepare_lines
from mdroll.provenance import environment

#: (lanes, steps a lane, registers) tried at thesis scale besides the default choice, each with and
#: without the delay line
LAYOUTS = ((128, 8, 128), (128, 8, 112), (128, 8, 96), (64, 8, 96), (256, 8, 128), (256, 8, 96), (256, 4, 128))


def kernel_ms(prepared, p, device, repeats, form, layout=None, check=None, delay=None):
    """Median force-kernel time (ms) and max |F - check| / F_N."""
    default = sweep.STREAM_LAYOUTS
    if layout:
        sweep.STREAM_LAYOUTS = (layout,)
    try:
        command, force = sweep.sweep_command(prepared, p, p.d0, device, offset=p.F_N, form=form, delay=delay)
    finally:
        sweep.STREAM_LAYOUTS = default
    command.launch()
    median, _ = device_timed(command.launch, device, repeats)
    values = force.numpy()
    error = None if check is None else float(np.max(np.abs(values - check)) / p.F_N)
    return median * 1e3, error, values


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--out", default="sweep_stream.json")
    args = parser.parse_args()
    device = resolve_device(args.device)
    p, count = Params(L=5.24288), 300
    record = {"environment": environment(device), "thesis": {}}
    record["thesis"]["edge_ms"] = force_time(p, "edge", count, device, args.repeats, "open")["force_s"] * 1e3
    lines = to_warp(rough_lines(p, 0, count, device=device), device)
    prepared = prepare_lines(lines, p, "sweep", "open", p.d0, device, h_max=H_BOUND_SIGMAS * p.h0)
    sequential_ms, _, reference = kernel_ms(prepared, p, device, args.repeats, "sequential")
    record["thesis"]["sequential_ms"] = sequential_ms
    stream_ms, error, _ = kernel_ms(prepared, p, device, args.repeats, "stream", check=reference)
    record["thesis"]["stream_default"] = {"ms": stream_ms, "max_abs_minus_sequential_over_F_N": error}
    print(f"edge {record['thesis']['edge_ms']:.3f} ms, sequential {sequential_ms:.3f} ms, stream {stream_ms:.3f} ms",
          flush=True)
    for layout in LAYOUTS:
        for delay in (True, False):
            ms, error, _ = kernel_ms(prepared, p, device, args.repeats, "stream", layout, reference, delay)
            name = "x".join(map(str, layout)) + ("-delay" if delay else "")
            record["thesis"][name] = {"ms": ms, "max_abs_minus_sequential_over_F_N": error}
            print(f"stream {name}: {ms:.3f} ms ({error:.1e} F_N)", flush=True)
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
