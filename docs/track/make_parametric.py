"""The numbers and the figure of docs/track.md, "The moving load over discrete supports":
``python docs/track/make_parametric.py`` (about a minute on a CPU).

Writes parametric.json and parametric.png beside this file and prints the page's tables.
"""

import json
from pathlib import Path

import matplotlib

matplotlib.use("agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from mdroll import Params  # noqa: E402
from mdroll.roughness.tables import iso3095_limit  # noqa: E402
from mdroll.track import Track  # noqa: E402
from mdroll.track.periodic import point_receptance  # noqa: E402
from mdroll.track.parametric import bay_receptance, harmonics, roughness_levels, static_receptance  # noqa: E402

HERE = Path(__file__).resolve().parent
NAMES = ("ballasted-soft-pad", "ballasted-stiff-pad", "slab")
#: Wheel loads (N): the thesis's static load and two typical ones (passenger and freight wheels).
LOADS = (Params().F_N, 75e3, 110e3)
#: Speeds (km/h): the thesis's v0 = 10 m/s and typical ones.
SPEEDS_KMH = (Params().v0 * 3.6, 80.0, 120.0, 160.0, 200.0)
#: The exact line's speeds (km/h), its harmonics tabulated and the damping models.
MOVING_KMH = SPEEDS_KMH + (300.0,)
COUNT = 4
DAMPINGS = ("causal", "hysteretic")


def moving_record(track, limit_630):
    """The exact line at the thesis's load at each speed and damping model: the levels (dB re 1 um)
    of its first :data:`COUNT` harmonics, their difference from the quasi-static line's (dB), and
    the load whose fundamental reaches the limit of the 630 mm band (kN)."""
    quasi = harmonics(track, LOADS[0], COUNT)[1]
    record = {}
    for damping in DAMPINGS:
        damped = track.with_values(damping=damping)
        rows = {}
        for kmh in MOVING_KMH:
            exact = harmonics(damped, LOADS[0], COUNT, speed=kmh / 3.6)[1]
            level = 20 * np.log10(exact / 1e-6)
            rows[f"{kmh:g} km/h"] = {
                "level_dB": np.round(level, 2).tolist(),
                "minus_quasi_static_dB": np.round(20 * np.log10(exact / quasi), 2).tolist(),
                # L(F) = L(F0) + 20 lg (F / F0)
                "load_at_limit_630mm_kN": round(float(LOADS[0] * 10 ** ((limit_630 - level[0]) / 20) / 1e3), 1),
            }
        record[damping] = rows
    return record


def preset_record(name):
    track = Track.preset(name)
    d = track.sleeper_spacing
    above, middle = static_receptance(track, [0.0, d / 2])
    lam, level_limit = iso3095_limit()
    # the dynamic model without losses (every modulus the elastic one) at 0.5 Hz against the static solve
    quiet = track.with_values(pad_loss=0.0, ballast_loss=0.0, rail_loss=0.0)
    dynamic = [float(point_receptance(0.5, quiet, p).real) for p in ("sleeper", "midspan")]
    loads = {}
    for load in LOADS:
        levels = roughness_levels(track, load, lam)
        held = np.isfinite(levels)
        loads[f"{load / 1e3:g} kN"] = {
            "bands_mm": lam[held].tolist(), "level_dB": np.round(levels[held], 2).tolist(),
            "limit_dB": level_limit[held].tolist(),
            "exceeds_mm": lam[held][levels[held] > level_limit[held]].tolist(),
        }
    fundamental = roughness_levels(track, 1.0, [630.0])[0]
    limit_630 = float(level_limit[lam == 630.0][0])
    return {
        "alpha_sleeper_m_per_N": float(above), "alpha_midspan_m_per_N": float(middle),
        "variation_percent": float(100 * (middle - above) / above),
        "dynamic_0p5Hz_over_static": [dynamic[0] / above, dynamic[1] / middle],
        "harmonics_rms_um_at_thesis_load": (harmonics(track, LOADS[0], 5)[1] * 1e6).round(4).tolist(),
        "loads": loads,
        # the load whose fundamental (630 mm band) reaches the limit: L(F) = L(1 N) + 20 lg F
        "load_at_limit_630mm_kN": float(10 ** ((limit_630 - fundamental) / 20) / 1e3),
        "sleeper_passing_Hz": {f"{kmh:g} km/h": kmh / 3.6 / d for kmh in MOVING_KMH},
        "moving": moving_record(track, limit_630),
    }


def figure(record):
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 3.8))
    lam, limit = iso3095_limit()
    for name, colour in zip(NAMES, ("C0", "C1", "C2")):
        track = Track.preset(name)
        x, alpha = bay_receptance(track, 256)
        left.plot(np.append(x, track.sleeper_spacing) / track.sleeper_spacing, np.append(alpha, alpha[0]) * 1e9,
                  colour, label=name)
        levels = roughness_levels(track, LOADS[0], lam)
        right.semilogx(lam, levels, colour + "o", label=f"{name}, {LOADS[0] / 1e3:g} kN")
        right.semilogx(lam, levels + 20 * np.log10(LOADS[1] / LOADS[0]), colour + "x",
                       label=f"{name}, {LOADS[1] / 1e3:g} kN")
    left.set(xlabel="load position x / d (0: above a sleeper)", ylabel="static receptance (1e-9 m/N)")
    left.legend(fontsize=7)
    left.grid(True, alpha=0.3)
    right.semilogx(lam, limit, "k--", label="EN ISO 3095 limit")
    right.set(xlabel="wavelength (mm)", ylabel="level (dB re 1 um)", ylim=(-40, 30))
    right.invert_xaxis()
    right.legend(fontsize=6)
    right.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(HERE / "parametric.png", dpi=110)


def main():
    record = {name: preset_record(name) for name in NAMES}
    (HERE / "parametric.json").write_text(json.dumps(record, indent=1) + "\n")
    figure(record)
    for name, r in record.items():
        print(name, json.dumps({k: v for k, v in r.items() if k not in ("loads", "moving")}))
        for damping, rows in r["moving"].items():
            for speed, row in rows.items():
                print("  ", damping, speed, json.dumps(row))
        for load, bands in r["loads"].items():
            print("  ", load, list(zip(bands["bands_mm"][:5], bands["level_dB"][:5], bands["limit_dB"][:5])),
                  "exceeds", bands["exceeds_mm"])


if __name__ == "__main__":
    main()
