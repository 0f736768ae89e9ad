"""Coupled mode (eq 13): the coupled kernel alone against the realizations a launch holds, the
band's width (dx), the realizations (warps) a block and the helper warps a realization
(``--helpers``, default the launch's own choice), rigid and on a track preset; each the
median wall time of a few launches, the device synchronized around each
(:func:`mdroll.bench.timed`; a launch takes ~0.1-1 s, its host set-up ~1 ms), on lines prepared
once, with the time a step takes per launch (the floor's unit: one dependent chain).

    python benchmarks/coupled_scaling.py --device cuda:0 --out coupled_scaling.json
    python benchmarks/coupled_scaling.py --device cpu --steps-log2 12 --realizations 2 3 --dx 2e-5 --warps 4 \
        --tracks rigid --out small.json
"""

import argparse
import json

from mdroll import Params
from mdroll.bench import timed
from mdroll.ensemble.coupled import contact_compliance, coupled_series
from mdroll.ensemble.lines import rough_lines
from mdroll.forces.prepare import prepare_lines
from mdroll.devices import resolve_device
from mdroll.provenance import environment
from mdroll.track import Track


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--out", default="coupled_scaling.json")
    parser.add_argument("--steps-log2", type=int, default=18, help="springs a line: 2^this")
    parser.add_argument("--algorithms", nargs="+", default=["sweep", "tree"])
    parser.add_argument("--realizations", type=int, nargs="+", default=[75, 150, 300, 600, 1200, 2400, 4800])
    parser.add_argument("--dx", type=float, nargs="+", default=[10e-6, 5e-6, 2.5e-6], help="spring spacings (m)")
    parser.add_argument("--warps", type=int, nargs="+", default=[1, 2, 4, 8], help="realizations a block (CUDA)")
    parser.add_argument("--tracks", nargs="+", default=["rigid", "ballasted-soft-pad"])
    parser.add_argument("--helpers", type=int, nargs="+", default=None,
                        help="helper warps a realization (CUDA; default: the launch's choice)")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    device = resolve_device(args.device)
    record = {"environment": environment(device), "steps_log2": args.steps_log2, "runs": []}
    base_dx = 5e-6
    # (algorithm, dx, realizations, warps, track): every count at the default layout and dx,
    # every layout at two counts, every dx and track at two counts
    cases = []
    for algorithm in args.algorithms:
        for track in args.tracks:
            counts = args.realizations if track == "rigid" else [c for c in args.realizations if c in (300, 1200, 4800)]
            cases += [(algorithm, base_dx, count, None, track) for count in counts]
        for count in (300, 1200):
            cases += [(algorithm, dx, count, None, "rigid") for dx in args.dx if dx != base_dx]
            cases += [(algorithm, base_dx, count, warps, "rigid") for warps in args.warps]
    prepared_for = {}
    cases = [(*case, helpers) for case in cases for helpers in (args.helpers or [None])]
    for algorithm, dx, count, warps, track, helpers in cases:
        params = Params(dx=dx, L=dx * 2 ** args.steps_log2)
        key = (algorithm, dx, count)
        if key not in prepared_for:
            prepared_for.clear()  # one set of lines on the device at a time
            lines = rough_lines(params, 1, count, device)
            prepared_for[key] = prepare_lines(lines, params, algorithm, "open", params.d0, device)
        prepared = prepared_for[key]
        compliance = contact_compliance(Track.preset(track), None)
        def launch():
            return coupled_series(prepared, params, algorithm, device, compliance=compliance, warps=warps,
                                  helpers=helpers)

        launch()  # compile, warm
        seconds, times = timed(launch, device, args.repeats)
        run = {"algorithm": algorithm, "dx": dx, "realizations": count, "warps": warps, "helpers": helpers,
               "track": track, "steps": prepared.steps, "seconds": seconds, "times": times,
               "ns_per_step": seconds / prepared.steps * 1e9}
        record["runs"].append(run)
        print(f"{algorithm:<6} dx {dx:.2e} R {count:5d} warps {warps or '-'!s:>2} helpers {helpers!s:>4} "
              f"{track:<20} {seconds:8.4f} s {run['ns_per_step']:8.1f} ns/step", flush=True)
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
