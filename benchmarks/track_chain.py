"""The frequency-domain chain of the track alone: the wall time of every preset's point
receptance (above a sleeper and at mid-span, as ``mdroll track receptance`` computes them: 400
log-spaced frequencies from 5 Hz to 10 kHz) and of its decay rates in the 1/3-octave bands of
EN ISO 3095 (``mdroll track decay``), after one warm-up pass.

    python benchmarks/track_chain.py --out track_chain.json
"""

import argparse
import json
import time

import numpy as np

from mdroll.provenance import environment
from mdroll.track import PRESETS, Track, decay_rate, iso3095_decay_limit, receptance


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="track_chain.json")
    parser.add_argument("--points", type=int, default=400)
    args = parser.parse_args()
    f = np.geomspace(5.0, 10_000.0, args.points)
    bands = iso3095_decay_limit()[0]
    tracks = {name: Track.preset(name) for name in PRESETS if name != "rigid"}
    record = {"environment": environment("cpu"), "points": args.points, "runs": {}}
    for track in tracks.values():  # warm-up
        receptance(track, f[:4], "sleeper")
        decay_rate(track, bands[:2])
    for name, track in tracks.items():
        run = {}
        for position in ("sleeper", "midspan"):
            start = time.perf_counter()
            receptance(track, f, position)
            run[f"receptance_{position}_s"] = time.perf_counter() - start
        start = time.perf_counter()
        decay_rate(track, bands)
        run["decay_s"] = time.perf_counter() - start
        record["runs"][name] = run
        print(name, {k: round(v, 4) for k, v in run.items()}, flush=True)
    record["total_sleeper_and_decay_s"] = sum(r["receptance_sleeper_s"] + r["decay_s"] for r in record["runs"].values())
    record["total_s"] = sum(sum(r.values()) for r in record["runs"].values())
    print(f"all presets: sleeper + decay {record['total_sleeper_and_decay_s']:.3f} s, "
          f"with mid-span {record['total_s']:.3f} s")
    with open(args.out, "w") as file:
        json.dump(record, file, indent=1)


if __name__ == "__main__":
    main()
