"""The tables of docs/track.md, "The moving load over discrete supports", on the exact line:
``python docs/track/make_moving_load.py`` (a few seconds a preset on a CPU).

Prints, for each preset and speed, the levels of the first harmonics of the exact moving load's
equivalent roughness at the thesis's wheel load and their difference from the quasi-static line's,
the exact line's cost a (track, speed) on this CPU, and the share of the quasi-static line's mean
square beyond the exact line's harmonics.
"""

import time

import numpy as np

from mdroll import Params
from mdroll.track import Track
from mdroll.track.parametric import MOVING_HARMONICS, harmonics, moving_bay_roughness, quasi_static_frequency

NAMES = ("ballasted-soft-pad", "ballasted-stiff-pad", "slab")
#: Speeds (km/h): the thesis's v0 = 10 m/s and typical ones.
SPEEDS_KMH = (Params().v0 * 3.6, 120.0, 200.0, 300.0)
#: Harmonics tabulated.
COUNT = 4


def level(rms):
    """dB re 1 um."""
    return 20.0 * np.log10(rms / 1e-6)


def main():
    load = Params().F_N
    print(f"harmonics n = 1..{COUNT} at {load / 1e3:g} kN: exact level dB re 1 um (exact - quasi-static dB)")
    print("| preset | speed | " + " | ".join(f"n = {n}" for n in range(1, COUNT + 1)) + " | cost (s) |")
    print("|---|---|" + "---|" * (COUNT + 1))
    for name in NAMES:
        track = Track.preset(name)
        quasi = harmonics(track, load, COUNT)[1]
        cells = " | ".join(f"{level(r):.1f}" for r in quasi)
        print(f"| {name} | quasi-static (f_qs = {quasi_static_frequency(track):.0f} Hz) | {cells} | |")
        for kmh in SPEEDS_KMH:
            moving_bay_roughness.cache_clear()
            start = time.perf_counter()
            exact = harmonics(track, load, COUNT, speed=kmh / 3.6)[1]
            cost = time.perf_counter() - start
            cells = " | ".join(f"{level(e):.1f} ({level(e) - level(q):+.2f})" for e, q in zip(exact, quasi))
            print(f"| {name} | {kmh:g} km/h, v/d = {kmh / 3.6 / track.sleeper_spacing:.1f} Hz | {cells} | {cost:.2f} |")
    for name in NAMES:
        rms = harmonics(Track.preset(name), 1.0, 511)[1]
        share = np.sum(rms[MOVING_HARMONICS:] ** 2) / np.sum(rms**2)
        print(f"{name}: mean square of the quasi-static line beyond harmonic {MOVING_HARMONICS}: {share:.2e} of it")


if __name__ == "__main__":
    main()
