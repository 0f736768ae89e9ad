"""The figures and numbers of docs/track.md: ``python docs/track/make_figures.py`` (seconds, CPU).

Writes receptance.png, decay.png, levels.png and checks.json beside this file.
"""

import json
import math
from pathlib import Path

import matplotlib

matplotlib.use("agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from mdroll import Params  # noqa: E402
from mdroll.roughness import iso3095  # noqa: E402
from mdroll.track import (REF_FORCE, REF_VELOCITY, Track, band_levels, continuous_receptance,  # noqa: E402
                          cut_on_frequencies, decay_rate, discrete_receptance, iso3095_decay_limit,
                          linear_chain, per_hz_one_sided, pinned_pinned_frequency, receptance,
                          third_octave_centres)
from mdroll.wheel import Wheel  # noqa: E402

HERE = Path(__file__).resolve().parent
NAMES = ("ballasted-soft-pad", "ballasted-stiff-pad", "slab")
BANDS = third_octave_centres(100, 5000)
SPEED = 100 / 3.6  # m/s: 100 km/h


def receptance_figure():
    f = np.geomspace(20, 5000, 1500)
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for name, colour in zip(NAMES, ("C0", "C1", "C2")):
        track = Track.preset(name)
        ax.loglog(f, np.abs(receptance(track, f, "sleeper")), colour, label=f"{name}, above a sleeper")
        ax.loglog(f, np.abs(receptance(track, f, "midspan")), colour + "--", label=f"{name}, mid-span")
    ax.set(xlabel="frequency (Hz)", ylabel="|rail point receptance| (m/N)", ylim=(1e-11, 1e-7))
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(HERE / "receptance.png", dpi=110)


def decay_figure():
    fig, ax = plt.subplots(figsize=(7, 4.2))
    rates = {}
    for name in NAMES:
        rates[name] = decay_rate(Track.preset(name), BANDS)
        ax.semilogy(BANDS, rates[name], "o-", label=name)
    limit_f, limit = iso3095_decay_limit()
    ax.semilogy(limit_f, limit, "k--", label="EN ISO 3095:2013 limit (vertical)")
    ax.set_xscale("log")
    ax.set(xlabel="1/3-octave band (Hz)", ylabel="decay rate (dB/m)")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(HERE / "decay.png", dpi=110)
    return {name: [round(float(r), 2) for r in values] for name, values in rates.items()}


def chain_levels():
    """1/3-octave levels of the linear chain: EN ISO 3095 limit roughness at 100 km/h, thesis contact."""
    p = Params()
    f = np.geomspace(80, 6000, 3000)
    q = 2 * math.pi * f / SPEED
    rough = iso3095().mdr_psd(q)
    rails = {name: receptance(Track.preset(name), f) for name in ("rigid",) + NAMES}
    levels = {}
    for wheel_name in ("rigid", "standard-920"):
        alpha_w = Wheel.preset(wheel_name).receptance(f)
        for name, alpha_r in rails.items():
            out = linear_chain(f, rough, alpha_w, alpha_r, p.k_contact, p.a, SPEED)
            row = {"force_dB_re_1N": band_levels(f, per_hz_one_sided(out["force"], SPEED), BANDS, REF_FORCE)}
            for part in ("wheel_velocity", "rail_velocity"):
                if np.any(out[part] > 0):
                    row[part + "_dB_re_1nm_s"] = band_levels(f, per_hz_one_sided(out[part], SPEED), BANDS, REF_VELOCITY)
            levels[f"{wheel_name} wheel, {name} track"] = {k: [round(float(v), 1) for v in vals] for k, vals in row.items()}
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for key in ("rigid wheel, rigid track", "rigid wheel, ballasted-soft-pad track",
                "rigid wheel, ballasted-stiff-pad track", "standard-920 wheel, ballasted-soft-pad track"):
        ax.semilogx(BANDS, levels[key]["force_dB_re_1N"], "o-", label=key)
    ax.set(xlabel="1/3-octave band (Hz)", ylabel="contact force (dB re 1 N)")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(HERE / "levels.png", dpi=110)
    return levels


def checks():
    """The numbers of the tests' checks (tests/test_track.py), for the page."""
    out = {}
    euler = Track(rail_shear_stiffness=math.inf, rail_rotary_inertia=0.0, rail_loss=0.0, pad_loss=0.0,
                  sleeper_mass=0.0, ballast_stiffness=1e16)
    beta = (euler.pad_stiffness / euler.sleeper_spacing / (4 * euler.rail_EI)) ** 0.25
    winkler = 1 / (8 * euler.rail_EI * beta**3)
    out["winkler_static_m_per_N"] = [winkler, float(continuous_receptance(1e-3, euler).real)]
    one = Track(pad_loss=0.02, rail_loss=0.0, sleeper_mass=0.0, ballast_stiffness=1e16)
    f0 = float(cut_on_frequencies(one)[0])
    grid = np.linspace(0.5 * f0, 1.5 * f0, 2001)
    out["single_layer_Hz"] = [f0, float(grid[np.argmax(np.abs(continuous_receptance(grid, one)))])]
    two = Track(pad_loss=0.02, ballast_loss=0.02, rail_loss=0.0)
    out["two_layer_Hz"] = []
    for fc in cut_on_frequencies(two):
        grid = np.linspace(0.8 * fc, 1.2 * fc, 2001)
        out["two_layer_Hz"].append([float(fc), float(grid[np.argmax(np.abs(continuous_receptance(grid, two)))])])
    track = Track(support="discrete")
    f = np.array([10.0, 20.0, 50.0])
    smeared = continuous_receptance(f, track)
    out["discrete_over_continuous_10_20_50Hz"] = {
        "above_sleeper": [round(float(v), 4) for v in np.abs(discrete_receptance(f, track) / smeared)],
        "mid_span": [round(float(v), 4) for v in np.abs(discrete_receptance(f, track, x0=0.3) / smeared)]}
    out["pinned_pinned_Hz"] = {}
    for name in NAMES:
        tr = Track.preset(name)
        f_pp = float(pinned_pinned_frequency(tr))
        grid = np.linspace(0.85 * f_pp, 1.15 * f_pp, 601)
        mid = np.abs(discrete_receptance(grid, tr, x0=0.5 * tr.sleeper_spacing))
        out["pinned_pinned_Hz"][name] = [round(f_pp, 1), round(float(grid[np.argmax(mid)]), 1)]
    eb = Track(rail_shear_stiffness=math.inf, rail_rotary_inertia=0.0)
    out["pinned_pinned_euler_Hz"] = round(float(pinned_pinned_frequency(eb)), 1)
    out["cut_on_Hz"] = {name: [round(float(v), 1) for v in cut_on_frequencies(Track.preset(name))] for name in NAMES}
    return out


if __name__ == "__main__":
    receptance_figure()
    record = {"bands_Hz": [round(float(b), 1) for b in BANDS], "decay_dB_per_m": decay_figure(),
              "levels": chain_levels(), "checks": checks(), "speed_m_per_s": SPEED}
    (HERE / "checks.json").write_text(json.dumps(record, indent=1) + "\n")
    print(json.dumps(record["checks"], indent=1))
