"""The wheel on a compliant track under small and large roughness: the coupled time-domain run
(:func:`mdroll.run_ensemble` with a track, the exact non-linear MDR contact) against the linear
frequency-domain chain (:func:`mdroll.track.linear_chain`, the TWINS chain with the MDR contact
filter and the track's closed-form receptance).

Roughness: the EN ISO 3095 limit spectrum shifted by each of the rung's offsets (dB): far below
it (-40 dB) the contact stays linear and the two must agree (the small-roughness check), at the
limit and 10 dB above it they part: the contact is lost on some steps, the contact filter's
sin^2 dips (``sinc(q a) = 0`` at ``q = n pi / a``, ``f_n = n v0 / (2 a)``) fill, and the band
levels leave the chain's. Tracks: the rigid rail (today's model), the soft-pad and the stiff-pad
ballasted track, under the rigid wheel (eq 13's mass). Default estimator (open record, Hann
window); the same realizations (seed) for every case.

Per case: the fraction of steps with contact lost, the 1/3-octave levels of the contact force
(dB re 1 N) and of the rail's and the wheel's velocity at the contact (dB re 1 nm/s,
:mod:`mdroll.ensemble.vibration`) against the chain's, with the standard error of each band, and
the force PSD in the dips against the chain's (sum over the bins within :data:`DIP_BINS` of each
dip). The smallest offset also gets the chain applied to the blocked force of the same
realizations (the decoupled run on the rigid rail: ``k_c sinc(q a) r``), which removes the
ensemble's sampling error: the check of the time stepping and the state-space fit alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import roughness
from ..ensemble.pipeline import run_ensemble
from ..experiments import Figure, Ladder
from ..params import Params
from ..physics import TWO_PI
from ..roughness import bands, tables
from ..track import Track, linear_chain, receptance

#: Tracks compared, under the rigid wheel.
TRACKS = ("rigid", "ballasted-soft-pad", "ballasted-stiff-pad")
#: Offsets from the EN ISO 3095 limit (dB): the small-roughness check, the limit, 10 dB above.
OFFSETS_DB = (-40.0, 0.0, 10.0)
#: Frequency range of the comparison (Hz) and the small-roughness tolerance per band (dB).
BAND_HZ = (100.0, 5000.0)
SMALL_DB = 0.5
#: Standard errors a band of the small-roughness ensemble may add to the tolerance against the chain.
Z_SIGMA = 3.0
#: Bins on each side of a contact-filter zero that make up its dip.
DIP_BINS = 2
#: Bins a band needs to be compared.
MIN_BINS = 3
#: Frequency (Hz) up to which the chain is evaluated: the top band's upper edge and the dips' bins.
TOP_HZ = 1.2 * BAND_HZ[1]


@dataclass(frozen=True)
class TrackSize:
    """A rung: the line (length, spacing; v0 = 10 m/s puts five dips below 5 kHz), the
    realizations, and the tracks and offsets it runs."""

    params: Params
    realizations: int
    tracks: tuple = TRACKS
    offsets_db: tuple = OFFSETS_DB


SIZES = Ladder(
    test=TrackSize(Params(L=1.0, dx=1e-4), 2, tracks=("rigid", "ballasted-soft-pad"), offsets_db=(-40.0, 10.0)),
    quick=TrackSize(Params(L=2.0, dx=1e-4), 4),
    full=TrackSize(Params(L=10.48576, dx=1e-5), 300),
)


def iso_spectrum(offset_db: float):
    """The EN ISO 3095 limit spectrum shifted by ``offset_db``."""
    wavelengths, levels = tables.iso3095_limit()
    return roughness.BandLevels(wavelengths, levels + offset_db, kind="profile",
                                source=f"EN ISO 3095 limit {offset_db:+g} dB")


def chain(params: Params, track: Track, spectrum, q) -> dict:
    """The linear chain's spectra at the record's wavenumbers ``q`` (two-sided per rad/m, like
    the run's; 0 at q = 0 and above :data:`TOP_HZ`: the discrete track's receptance costs a
    Brillouin-zone sum per frequency), the roughness the spectrum's MDR PSD cut at q_max, the
    rigid wheel of mass m."""
    q = np.asarray(q, dtype=np.float64)
    inside = (q > 0) & (q * params.v0 / TWO_PI <= TOP_HZ)
    f = q[inside] * params.v0 / TWO_PI
    c_r = np.where(q[inside] <= params.q_max, spectrum.mdr_psd(q[inside]), 0.0)
    spectra = linear_chain(f, c_r, -1.0 / (params.m * (TWO_PI * f) ** 2), receptance(track, f), params.k_contact,
                           params.a, params.v0)
    out = {}
    for key, values in spectra.items():
        out[key] = np.zeros(q.shape, dtype=values.dtype)
        out[key][inside] = values
    return out


def band_difference(q, psd, stderr, reference, params: Params, quantity: str) -> dict:
    """1/3-octave levels of ``psd`` and ``reference`` over :data:`BAND_HZ` (bands of at least
    :data:`MIN_BINS` bins), their difference (dB) and its standard error (dB, the bins
    independent)."""
    dq = float(q[1] - q[0])
    n = bands.band_numbers(np.array(BAND_HZ))
    n = np.arange(n[0], n[1] + 1)
    lo, hi = bands.frequency_band_edges_q(n, params.v0)
    ms, counts = bands.band_mean_squares(q, psd, dq, lo, hi)
    ms_ref, _ = bands.band_mean_squares(q, reference, dq, lo, hi)
    var = np.array([np.sum((2 * dq * stderr[(q >= a) & (q < b)]) ** 2) for a, b in zip(lo, hi)])
    ok = counts >= MIN_BINS
    ref = bands.REFERENCES[quantity]
    level, level_ref = bands.level_db(ms[ok], ref), bands.level_db(ms_ref[ok], ref)
    return {"frequency_Hz": bands.nominal(n[ok]).tolist(), "level_dB": level.tolist(),
            "linear_dB": level_ref.tolist(), "difference_dB": (level - level_ref).tolist(),
            "stderr_dB": (10 * np.log10(1 + np.sqrt(var[ok]) / ms[ok])).tolist()}


def dips(q, force_psd, linear_psd, params: Params) -> list:
    """Per contact-filter zero below :data:`BAND_HZ`'s top: its frequency, and the force PSD
    summed over the :data:`DIP_BINS` bins on each side of it against the chain's (dB)."""
    out = []
    dq = float(q[1] - q[0])
    n = 1
    while n * params.v0 / (2 * params.a) <= BAND_HZ[1]:
        k = int(round(n * np.pi / params.a / dq))
        window = slice(k - DIP_BINS, k + DIP_BINS + 1)
        out.append({"n": n, "frequency_Hz": n * params.v0 / (2 * params.a),
                    "over_linear_dB": float(10 * np.log10(np.sum(force_psd[window]) / np.sum(linear_psd[window])))})
        n += 1
    return out


def track_study(size: TrackSize, seed: int = 0, device: str = "cpu") -> dict:
    """The study (module docstring) at one rung: a JSON-ready record. ``passed``: the
    small-roughness check on the compliant tracks, every band within :data:`SMALL_DB` of the
    chain on the same realizations (the rigid rail's undamped contact resonance, a singularity
    of both, is reported only). ``analytic_within_z_sigma`` per small-roughness case: every band
    within :data:`SMALL_DB` plus :data:`Z_SIGMA` standard errors of the analytic chain (its
    spectrum, not the realizations': meaningful with many realizations)."""
    p = size.params
    common = dict(seed=seed, realizations=size.realizations, device=device, progress=False)
    cases, passed = [], True
    smallest = min(size.offsets_db)
    for offset in size.offsets_db:
        spectrum = iso_spectrum(offset)
        blocked = run_ensemble(p, roughness=spectrum, **common) if offset == smallest else None
        for name in size.tracks:
            track = Track.preset(name)
            run = run_ensemble(p, mode="coupled", track=track, roughness=spectrum, **common)
            linear = chain(p, track, spectrum, run.q)
            shown = (run.omega / TWO_PI >= BAND_HZ[0]) & (run.omega / TWO_PI <= BAND_HZ[1])
            vibration = _vibration(run)
            case = {"track": name, "offset_dB": offset, "line_rms_m": roughness.line_rms(p, spectrum),
                    "contact_lost_fraction": run.contact_lost_steps / (run.steps * run.n_real),
                    "force_rms_N": run.force_rms,
                    "force": band_difference(run.q, run.force_psd, run.force_psd_stderr, linear["force"], p, "force"),
                    "wheel_velocity": band_difference(run.q, *vibration["wheel_velocity"], linear["wheel_velocity"],
                                                      p, "velocity"),
                    "dips": dips(run.q, run.force_psd, linear["force"], p),
                    "narrow": {"frequency_Hz": (run.omega / TWO_PI)[shown].tolist(),
                               "force_psd": run.force_psd[shown].tolist(), "linear_force_psd": linear["force"][shown].tolist()}}
            if name != "rigid":
                case["rail_velocity"] = band_difference(run.q, *vibration["rail_velocity"], linear["rail_velocity"],
                                                        p, "velocity")
            if blocked is not None:
                case["same_realizations"] = _same_realizations(run, blocked, track, p)
                case["analytic_within_z_sigma"] = _analytic_within(case)
                if name != "rigid":
                    ok = all(np.max(np.abs(v)) <= SMALL_DB for v in case["same_realizations"].values())
                    case["small_roughness_passed"] = bool(ok)
                    passed = passed and ok
            cases.append(case)
    return {"params": p.as_dict(), "realizations": size.realizations, "a_m": p.a, "k_contact_N_per_m": p.k_contact,
            "band_Hz": list(BAND_HZ), "small_tolerance_dB": SMALL_DB, "z_sigma": Z_SIGMA, "cases": cases,
            "passed": passed}


def _vibration(run) -> dict:
    """The run's vibration spectra; on the rigid rail (which records no structures) the rigid
    wheel's velocity from its acceleration, ``S_a / omega^2``."""
    vibration = run.vibration()
    if not vibration:
        with np.errstate(divide="ignore", invalid="ignore"):
            w2 = np.where(run.omega > 0, run.omega**2, np.inf)
        vibration["wheel_velocity"] = (run.accel_psd / w2, run.accel_psd_stderr / w2)
    return vibration


def _same_realizations(run, blocked, track: Track, p: Params) -> dict:
    """The chain on the blocked force of the same realizations: force and velocities, per band."""
    keep = (run.q > 0) & (run.q * p.v0 / TWO_PI <= TOP_HZ)
    q = run.q[keep]
    f = q * p.v0 / TWO_PI
    alpha_w, alpha_r = -1.0 / (p.m * (TWO_PI * f) ** 2), receptance(track, f)
    transfer = 1.0 / np.abs(p.k_contact * (alpha_w + alpha_r + 1.0 / p.k_contact)) ** 2
    force = blocked.force_psd[keep] * transfer
    vib = _vibration(run)
    pairs = {"force": (run.force_psd[keep], force, "force"),
             "wheel_velocity": (vib["wheel_velocity"][0][keep], np.abs(TWO_PI * f * alpha_w) ** 2 * force, "velocity")}
    if "rail_velocity" in vib:
        pairs["rail_velocity"] = (vib["rail_velocity"][0][keep], np.abs(TWO_PI * f * alpha_r) ** 2 * force,
                                  "velocity")
    zero = np.zeros_like(q)
    return {key: band_difference(q, got, zero, linear, p, quantity)["difference_dB"]
            for key, (got, linear, quantity) in pairs.items()}


def _analytic_within(case: dict) -> bool:
    """Whether every band of force and velocities is within :data:`SMALL_DB` plus :data:`Z_SIGMA`
    standard errors of the analytic chain."""
    return bool(all(abs(d) <= SMALL_DB + Z_SIGMA * e for key in ("force", "wheel_velocity", "rail_velocity")
                    if key in case for d, e in zip(case[key]["difference_dB"], case[key]["stderr_dB"])))


def figures(record: dict) -> list:
    """track_bands.png (the force's and the rail's band levels less the chain's, per track and
    offset) and track_dips.png (the narrow-band force PSD against the chain's, soft-pad track)."""
    cases = record["cases"]
    tracks = list(dict.fromkeys(c["track"] for c in cases))

    def draw_bands(fig):
        axes = fig.subplots(2, len(tracks), squeeze=False, sharex=True)
        for column, name in enumerate(tracks):
            for row, key in enumerate(("force", "rail_velocity")):
                ax = axes[row][column]
                for c in (c for c in cases if c["track"] == name and key in c):
                    d = c[key]
                    ax.errorbar(d["frequency_Hz"], d["difference_dB"], yerr=d["stderr_dB"], marker="o", ms=3,
                                label=f"ISO 3095 {c['offset_dB']:+g} dB, contact lost "
                                      f"{100 * c['contact_lost_fraction']:.2g} %")
                ax.set_xscale("log")
                ax.axhline(0.0, color="k", lw=0.5)
                ax.set_title(f"{name}: {key.replace('_', ' ')}", fontsize=9)
                ax.set_ylabel("time domain - linear chain (dB)")
                ax.grid(True, which="both", alpha=0.3)
                if ax.get_legend_handles_labels()[0]:
                    ax.legend(fontsize=6)
            axes[1][column].set_xlabel("1/3-octave band (Hz)")

    def draw_dips(fig):
        shown = [c for c in cases if c["track"] == (tracks[1] if len(tracks) > 1 else tracks[0])]
        axes = fig.subplots(len(shown), 1, squeeze=False, sharex=True)
        for ax, c in zip(axes[:, 0], shown):
            n = c["narrow"]
            f = np.array(n["frequency_Hz"])
            keep = (f >= 300) & (f <= BAND_HZ[1])
            ax.loglog(f[keep], np.array(n["force_psd"])[keep], lw=0.8, label="time domain (MDR, non-linear)")
            ax.loglog(f[keep], np.array(n["linear_force_psd"])[keep], lw=0.8, label="linear chain")
            for dip in c["dips"]:
                ax.axvline(dip["frequency_Hz"], color="k", lw=0.4, ls=":")
            ax.set_title(f"{c['track']}, ISO 3095 {c['offset_dB']:+g} dB", fontsize=9)
            ax.set_ylabel("force PSD (N$^2$ m)")
            ax.legend(fontsize=7)
        axes[-1, 0].set_xlabel("frequency (Hz); dotted: zeros of the contact filter sinc(qa)")

    return [Figure("track_bands", "coupled run on a track against the linear chain, per 1/3-octave band", draw_bands,
                   size=(4 * len(tracks), 7), dpi=110),
            Figure("track_dips", "the contact filter's dips in the force PSD, time domain against the linear chain",
                   draw_dips, size=(8, 8), dpi=110)]
