"""The tables of docs/track.md, "The moving load over discrete supports", on the exact line:
``python docs/track/make_moving_load.py`` (about a minute on a CPU).

Prints, for each preset, damping model and speed, the levels of the first harmonics of the exact
moving load's equivalent roughness at the thesis's wheel load and their difference from the
quasi-static line's; beside them, the fundamental of the quasi-static line of the track whose
stiffnesses are their storage stiffnesses at v/d (the elastic limit of the softer causal track);
the exact line's cost a (track, speed) on this CPU; and the share of the quasi-static line's mean
square beyond the exact line's harmonics.
"""

import time

import numpy as np

from mdroll import Params
from mdroll.physics import TWO_PI
from mdroll.track import Track
from mdroll.track.beam import modulus
from mdroll.track.parametric import MOVING_HARMONICS, harmonics, moving_bay_roughness

NAMES = ("ballasted-soft-pad", "ballasted-stiff-pad", "slab")
DAMPINGS = ("causal", "hysteretic")
#: Speeds (km/h): the thesis's v0 = 10 m/s and typical ones.
SPEEDS_KMH = (Params().v0 * 3.6, 120.0, 200.0, 300.0)
#: Harmonics tabulated.
COUNT = 4


def level(rms):
    """dB re 1 um."""
    return 20.0 * np.log10(rms / 1e-6)


def storage_track(track, f):
    """The track with each stiffness replaced by its storage stiffness at ``f`` (Hz), Re k*."""
    omega = TWO_PI * f
    stiffness = {name: float(modulus(getattr(track, name), loss, omega, track).real) for name, loss in (
        ("pad_stiffness", track.pad_loss), ("ballast_stiffness", track.ballast_loss),
        ("rail_EI", track.rail_loss), ("rail_shear_stiffness", track.rail_loss))}
    return track.with_values(**stiffness)


def main():
    load = Params().F_N
    print(f"harmonics n = 1..{COUNT} at {load / 1e3:g} kN: exact level dB re 1 um (exact - quasi-static dB); "
          "r_p at v/d: the quasi-static fundamental of the storage stiffnesses at v/d (dB re the quasi-static)")
    print("| preset, damping | speed | " + " | ".join(f"n = {n}" for n in range(1, COUNT + 1))
          + " | r_p at v/d | cost (s) |")
    print("|---|---|" + "---|" * (COUNT + 2))
    for name in NAMES:
        for damping in DAMPINGS:
            track = Track.preset(name).with_values(damping=damping)
            quasi = harmonics(track, load, COUNT)[1]
            cells = " | ".join(f"{level(r):.1f}" for r in quasi)
            print(f"| {name}, {damping} | quasi-static | {cells} | | |")
            for kmh in SPEEDS_KMH:
                f = kmh / 3.6 / track.sleeper_spacing
                moving_bay_roughness.cache_clear()
                start = time.perf_counter()
                exact = harmonics(track, load, COUNT, speed=kmh / 3.6)[1]
                cost = time.perf_counter() - start
                softer = level(harmonics(storage_track(track, f), load, 1)[1][0]) - level(quasi[0])
                cells = " | ".join(f"{level(e):.1f} ({level(e) - level(q):+.2f})" for e, q in zip(exact, quasi))
                print(f"| {name}, {damping} | {kmh:g} km/h, v/d = {f:.1f} Hz | {cells} | {softer:+.2f} | {cost:.2f} |")
    for name in NAMES:
        rms = harmonics(Track.preset(name), 1.0, 511)[1]
        share = np.sum(rms[MOVING_HARMONICS:] ** 2) / np.sum(rms**2)
        print(f"{name}: mean square of the quasi-static line beyond harmonic {MOVING_HARMONICS}: {share:.2e} of it")


if __name__ == "__main__":
    main()
