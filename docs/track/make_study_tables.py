"""The track study's tables of docs/track.md from its record:
``python docs/track/make_study_tables.py RECORD.json`` (the ``roughness.json`` of
``mdroll roughness check --only track``, or a copy of it in benchmarks/results/).

Prints two markdown tables. Small roughness (the smallest offset): per track, the largest
|difference| from the linear chain over the bands of the record on the same realizations
(force, wheel velocity, rail velocity) with its band, and against the analytic chain (with the
band's standard error); on the rigid rail the band holding the undamped contact resonance
``sqrt(k_c / m) / (2 pi)`` is shown apart, a singularity of both models. Large roughness: per
track and offset, the fraction of steps with the contact lost, the force RMS, the force PSD in
the contact filter's dips over the chain's, and the largest signed band difference from the
analytic chain of the force and of the wheel's and the rail's velocity.
"""

import json
import math
import sys

import numpy as np

QUANTITIES = ("force", "wheel_velocity", "rail_velocity")
NAMES = {"rigid": "rigid", "ballasted-soft-pad": "soft pad", "ballasted-stiff-pad": "stiff pad"}


def band(hz: float) -> str:
    return f"{hz / 1000:g} kHz" if hz >= 1000 else f"{hz:g} Hz"


def largest(values, frequencies, skip=None):
    """(value, band) of the largest |value|, the band ``skip`` left out."""
    keep = [i for i, f in enumerate(frequencies) if f != skip]
    i = keep[int(np.argmax(np.abs(np.asarray(values)[keep])))]
    return values[i], frequencies[i]


def resonance_band(record: dict, frequencies) -> float:
    """The nominal band (of ``frequencies``) holding the rigid rail's contact resonance."""
    f = math.sqrt(record["k_contact_N_per_m"] / record["params"]["m"]) / (2 * math.pi)
    return min(frequencies, key=lambda nominal: abs(math.log(nominal / f)))


def small_table(record: dict) -> list:
    smallest = min(c["offset_dB"] for c in record["cases"])
    rows = ["| track | on the same realizations: force / wheel velocity / rail velocity (dB, band) "
            "| against the analytic chain: force / wheel / rail (dB, band; standard error) |",
            "|---|---|---|"]
    for case in (c for c in record["cases"] if c["offset_dB"] == smallest):
        frequencies = case["force"]["frequency_Hz"]
        skip = resonance_band(record, frequencies) if case["track"] == "rigid" else None
        same, analytic = [], []
        for key in QUANTITIES:
            if key not in case:
                same.append("-")
                analytic.append("-")
                continue
            values = case["same_realizations"][key]
            if len(values) != len(frequencies):
                raise SystemExit(f"{key}: {len(values)} bands on the same realizations, "
                                 f"{len(frequencies)} in the record")
            value, where = largest(values, frequencies, skip)
            text = f"{abs(value):.2f} ({band(where)})"
            if skip is not None:
                text += f"; {abs(values[frequencies.index(skip)]):.2f} in the {band(skip)} band"
            same.append(text)
            d = case[key]
            value, where = largest(d["difference_dB"], frequencies)
            analytic.append(f"{value:+.2f} ({band(where)}; {d['stderr_dB'][frequencies.index(where)]:.2f})")
        rows.append(f"| {NAMES.get(case['track'], case['track'])} | {' / '.join(same)} | {' / '.join(analytic)} |")
    return rows


def number(x: float) -> str:
    if x < 1000:
        return f"{x:.0f}" if x >= 10 else f"{x:.2g}"
    mantissa, exponent = f"{x:.1e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def lost(fraction: float) -> str:
    return "0" if fraction == 0 else f"{100 * fraction:.3g} %"


def large_table(record: dict) -> list:
    cases = sorted(record["cases"], key=lambda c: (list(NAMES).index(c["track"]) if c["track"] in NAMES else 9,
                                                   c["offset_dB"]))
    dips = " / ".join(f"{d['frequency_Hz']:.0f}" for d in cases[0]["dips"])
    rows = [f"| track, offset | contact lost | force RMS (N) | dips over the chain (dB), {dips} Hz "
            "| largest force difference from the chain (dB) | wheel / rail velocity (dB) |",
            "|---|---|---|---|---|---|"]
    for case in cases:
        signed = []
        for key in QUANTITIES:
            if key in case:
                value, where = largest(case[key]["difference_dB"], case[key]["frequency_Hz"])
                signed.append(f"{value:+.2f} ({band(where)})")
            else:
                signed.append("-")
        over = " / ".join(f"{d['over_linear_dB']:.1f}" for d in case["dips"])
        rows.append(f"| {NAMES.get(case['track'], case['track'])}, {case['offset_dB']:+g} dB "
                    f"| {lost(case['contact_lost_fraction'])} | {number(case['force_rms_N'])} | {over} "
                    f"| {signed[0]} | {signed[1]} / {signed[2]} |")
    return rows


def main(argv: list) -> int:
    if len(argv) != 1:
        raise SystemExit("usage: python docs/track/make_study_tables.py RECORD.json")
    try:
        with open(argv[0]) as f:
            record = json.load(f)
    except (OSError, ValueError) as err:
        raise SystemExit(f"{argv[0]}: not a readable JSON record ({err})")
    record = record.get("track", record)
    if "cases" not in record:
        raise SystemExit(f"{argv[0]}: no track study in it (a 'track' object with 'cases' is expected)")
    print(f"Small roughness (ISO 3095 {min(c['offset_dB'] for c in record['cases']):+g} dB), largest difference "
          f"from the linear chain over the bands {band(record['band_Hz'][0])}-{band(record['band_Hz'][1])}:\n")
    print("\n".join(small_table(record)))
    print("\nLarge roughness, per track and ISO 3095 offset:\n")
    print("\n".join(large_table(record)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
