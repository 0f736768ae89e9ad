"""Coupled mode (eq 13) on a compliant track against the rigid one: the wall time of one warm
:func:`mdroll.run_ensemble` call with the sweep at thesis scale (300 x 2^20, open boundary)
for the rigid track and each track preset (the rail's modal state space in the coupled step),
after one untimed rigid run at full size and a small warm-up run of each; with the floor's
count, modes x steps x realizations, and the ratio to the rigid run.

    python benchmarks/coupled_track.py --device cuda:0 --out coupled_track.json
    python benchmarks/coupled_track.py --device cpu --realizations 4 --length 0.05 --out small.json
"""

import argparse
import json
import time

from mdroll import Params, run_ensemble
from mdroll.devices import resolve_device, synchronize
from mdroll.ensemble.coupled import contact_compliance
from mdroll.provenance import environment
from mdroll.track import PRESETS, Track


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cuda:0")
    parser.add_argument("--out", default="coupled_track.json")
    parser.add_argument("--realizations", type=int, default=300)
    parser.add_argument("--length", type=float, default=5.24288, help="line length L (m); 2^20 steps at dx = 5 um")
    args = parser.parse_args()
    device = resolve_device(args.device)
    p = Params(L=args.length)
    record = {"environment": environment(device), "params": p.as_dict(), "realizations": args.realizations,
              "runs": {}}
    # the first run at full size pays the device's first use of it (buffers, FFT plans)
    run_ensemble(p, realizations=args.realizations, mode="coupled", device=device, progress=False)
    for name in PRESETS:
        track = Track.preset(name)
        form, _ = contact_compliance(track, None)  # the fit, outside the timing
        modes = 0 if form is None else form.order
        run_ensemble(Params(L=0.05), realizations=4, mode="coupled", device=device, progress=False, track=track)
        synchronize(device)
        start = time.perf_counter()
        result = run_ensemble(p, realizations=args.realizations, mode="coupled", device=device, progress=False,
                              track=track)
        wall = time.perf_counter() - start
        record["runs"][name] = {"wall_s": wall, "modes": modes, "steps": result.steps,
                                "mode_steps": modes * result.steps * args.realizations,
                                "contact_lost_steps": result.contact_lost_steps, "timings": result.timings}
        print(f"{name:<20} {wall:8.3f} s  modes {modes:3d}  ratio to rigid "
              f"{wall / record['runs']['rigid']['wall_s']:.2f}", flush=True)
    with open(args.out, "w") as f:
        json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
