"""The rail fits' table of docs/track.md, "State space": ``python docs/track/make_fits.py`` (about a
minute on a CPU).

For every preset and position, with the presets' causal damping and with hysteretic damping: the
passive fit the coupled run steps and the plain vector fit (:func:`mdroll.track.fit.rail_modal_form`),
their largest complex error over 50 Hz - 5 kHz (dB), their states and whether the passive one is
passive by the exact test. Writes fits.json beside this file.
"""

import json
import time
from pathlib import Path

from mdroll.track import Track
from mdroll.track.fit import rail_modal_form

HERE = Path(__file__).resolve().parent
NAMES = ("ballasted-soft-pad", "ballasted-stiff-pad", "slab")


def fits():
    out = {}
    for damping in ("causal", "hysteretic"):
        for name in NAMES:
            track = Track.preset(name).with_values(damping=damping)
            for position in ("sleeper", "midspan"):
                start = time.perf_counter()
                passive, plain = rail_modal_form(track, position), rail_modal_form(track, position, passive=False)
                out[f"{damping}/{name}/{position}"] = {
                    "passive_dB": round(passive.error_db, 6), "passive_states": passive.order,
                    "is_passive": passive.is_passive(), "plain_dB": round(plain.error_db, 6),
                    "plain_states": plain.order, "plain_is_passive": plain.is_passive(),
                    "seconds": round(time.perf_counter() - start, 1)}
                print(damping, name, position, out[f"{damping}/{name}/{position}"], flush=True)
    return out


if __name__ == "__main__":
    (HERE / "fits.json").write_text(json.dumps(fits(), indent=1) + "\n")
