"""The figures and numbers of docs/track.md: ``python docs/track/make_figures.py`` (seconds, CPU).

Writes receptance.png, decay.png, levels.png and checks.json beside this file: the presets with
their default, causal damping, and (``_hysteretic`` keys, dotted curves) the same tracks with
hysteretic damping for comparison.
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


def hysteretic(name):
    """The preset ``name`` with hysteretic damping."""
    return Track.preset(name).with_values(damping="hysteretic")


def receptance_figure():
    f = np.geomspace(20, 5000, 1500)
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for name, colour in zip(NAMES, ("C0", "C1", "C2")):
        track = Track.preset(name)
        ax.loglog(f, np.abs(receptance(track, f, "sleeper")), colour, label=f"{name}, above a sleeper")
        ax.loglog(f, np.abs(receptance(track, f, "midspan")), colour + "--", label=f"{name}, mid-span")
        ax.loglog(f, np.abs(receptance(hysteretic(name), f, "sleeper")), colour + ":", lw=1,
                  label=f"{name}, above a sleeper, hysteretic")
    ax.set(xlabel="frequency (Hz)", ylabel="|rail point receptance| (m/N)", ylim=(1e-11, 1e-7))
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(HERE / "receptance.png", dpi=110)


def decay_figure():
    fig, ax = plt.subplots(figsize=(7, 4.2))
    rates = {}
    for name, colour in zip(NAMES, ("C0", "C1", "C2")):
        rates[name] = decay_rate(Track.preset(name), BANDS)
        rates[name + "_hysteretic"] = decay_rate(hysteretic(name), BANDS)
        ax.semilogy(BANDS, rates[name], colour + "o-", label=name)
        ax.semilogy(BANDS, rates[name + "_hysteretic"], colour + ":", lw=1, label=f"{name}, hysteretic")
    limit_f, limit = iso3095_decay_limit()
    ax.semilogy(limit_f, limit, "k--", label="EN ISO 3095:2013 limit (vertical)")
    ax.set_xscale("log")
    ax.set(xlabel="1/3-octave band (Hz)", ylabel="decay rate (dB/m)")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(HERE / "decay.png", dpi=110)
    return {name: [round(float(r), 2) for r in values] for name, values in rates.items()}


def iso3095_decay():
    """The decay rates at the exact centres of the EN ISO 3095 limit's bands (``mdroll track decay``)."""
    bands, limit = iso3095_decay_limit()
    exact = 1000.0 * 10.0 ** (np.round(10 * np.log10(bands / 1000.0)) / 10)
    out = {"bands_Hz": bands.tolist(), "limit_dB_per_m": limit.tolist()}
    for name in NAMES:
        for key, track in ((name, Track.preset(name)), (name + "_hysteretic", hysteretic(name))):
            out[key] = [round(float(r), 2) for r in decay_rate(track, exact)]
    return out


def chain_levels():
    """1/3-octave levels of the linear chain: EN ISO 3095 limit roughness at 100 km/h, thesis contact."""
    p = Params()
    f = np.geomspace(80, 6000, 3000)
    q = 2 * math.pi * f / SPEED
    rough = iso3095().mdr_psd(q)
    rails = {name: receptance(Track.preset(name), f) for name in ("rigid",) + NAMES}
    rails.update({name + " (hysteretic)": receptance(hysteretic(name), f) for name in NAMES})
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
                  sleeper_mass=0.0, ballast_stiffness=1e16, ballast_loss=0.0)
    beta = (euler.pad_stiffness / euler.sleeper_spacing / (4 * euler.rail_EI)) ** 0.25
    winkler = 1 / (8 * euler.rail_EI * beta**3)
    out["winkler_static_m_per_N"] = [winkler, float(continuous_receptance(1e-3, euler).real)]
    one = Track(pad_loss=0.02, rail_loss=0.0, sleeper_mass=0.0, ballast_stiffness=1e16, damping="hysteretic")
    f0 = float(cut_on_frequencies(one)[0])
    grid = np.linspace(0.5 * f0, 1.5 * f0, 2001)
    out["single_layer_Hz"] = [f0, float(grid[np.argmax(np.abs(continuous_receptance(grid, one)))])]
    two = Track(pad_loss=0.02, ballast_loss=0.02, rail_loss=0.0, damping="hysteretic")
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
    # [formula, mid-span peak: hysteretic, causal at f_r = f_pp (the test), the causal preset (f_r = 100 Hz)]
    out["pinned_pinned_Hz"] = {}
    for name in NAMES:
        f_pp = float(pinned_pinned_frequency(Track.preset(name)))
        grid = np.linspace(0.85 * f_pp, 1.15 * f_pp, 601)
        row = [round(f_pp, 1)]
        for tr in (hysteretic(name), Track.preset(name).with_values(damping_frequency=f_pp), Track.preset(name)):
            mid = np.abs(discrete_receptance(grid, tr, x0=0.5 * tr.sleeper_spacing))
            row.append(round(float(grid[np.argmax(mid)]), 1))
        out["pinned_pinned_Hz"][name] = row
    eb = Track(rail_shear_stiffness=math.inf, rail_rotary_inertia=0.0)
    out["pinned_pinned_euler_Hz"] = round(float(pinned_pinned_frequency(eb)), 1)
    out["cut_on_Hz"] = {name: [round(float(v), 1) for v in cut_on_frequencies(Track.preset(name))] for name in NAMES}
    return out


if __name__ == "__main__":
    receptance_figure()
    record = {"bands_Hz": [round(float(b), 1) for b in BANDS], "decay_dB_per_m": decay_figure(),
              "iso3095_decay": iso3095_decay(), "levels": chain_levels(), "checks": checks(), "speed_m_per_s": SPEED}
    (HERE / "checks.json").write_text(json.dumps(record, indent=1) + "\n")
    print(json.dumps(record["checks"], indent=1))
