"""Physics checks of the roughness models by ensembles (above the ensemble layer).

Each function returns a JSON-ready dict of measured and predicted numbers with a ``passed`` flag
where there is a pass criterion; :data:`RAILWAY_STUDIES` registers them bound to a rung of the ladder
(:data:`SIZES`: "quick", small lines for a CPU; "full", thesis-scale ensembles for a GPU) and :func:`run_all` runs them
for ``mdroll roughness check``.

Ensembles go through :class:`mdroll.EnsembleSpec` / :func:`mdroll.run_specs`; the checks of the
force use the periodic boundary (physics.md section 6: no leakage, each bin the line's own mode).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import physics, roughness
from ..ensemble.lines import rough_lines
from ..ensemble.psd import psd_rows, to_host
from ..ensemble.spec import EnsembleSpec, run_specs
from ..experiments import Ladder, Registry, provenance
from ..forces.force import contact_force
from ..params import Params
from ..roughness import bands, filters, measured, tables
from . import track_study

#: Standard errors added to each model allowance (as mdroll.validation.checks).
Z_SIGMA = 3.0
#: dB tolerance of the round trip dB table -> PSD -> lines -> 1/3-octave levels.
ROUND_TRIP_DB = 0.3
#: Accel band-level difference (dB) up to which the decoupled mode counts as valid.
DECOUPLED_DB = 1.0


@dataclass(frozen=True)
class RailwaySize:
    """The studies' parameters on one rung of the ladder: a base for the line and force checks, one for eq 63 and one for the
    dynamics (long lines for the ISO 3095 spectrum's long waves), and the track study's rung
    (:mod:`mdroll.railway.track_study`)."""

    base: Params
    eq63: Params
    dynamics: Params
    n_real: int
    n_real_eq63: int
    track: track_study.TrackSize
    speeds: tuple = (10.0, 20.0, 30.0, 40.0)
    profile_length: float = 20.0


SIZES = Ladder(
    quick=RailwaySize(base=Params(L=0.5, dx=1e-5), eq63=Params(L=1.0, dx=1e-5), dynamics=Params(L=2.0, dx=5e-5),
                      n_real=8, n_real_eq63=16, track=track_study.SIZES["quick"], profile_length=8.0),
    full=RailwaySize(base=Params(L=5.0, dx=5e-6), eq63=Params(L=5.0, dx=5e-6), dynamics=Params(L=10.0, dx=5e-5),
                     n_real=32, n_real_eq63=300, track=track_study.SIZES["full"], profile_length=100.0),
)


def _host(array) -> np.ndarray:
    return to_host(array)


def line_spectrum_check(params: Params, spectrum, seed: int = 0, n_real: int = 4, device: str = "cpu") -> dict:
    """The ensemble PSD of generated lines against the requested C_1D(q_k) (:func:`mdroll.roughness.grid_psd`).

    Lines have fixed amplitudes and random phases (eq 16-17), so each line's periodogram on its
    own grid equals the requested spectrum up to the RMS scaling (which varies with the phase of
    the Nyquist mode): passes where every bin is within Z_SIGMA standard errors plus the Nyquist
    mode's share of the mean square and 1e-9 (rounding) of the largest bin."""
    lines = rough_lines(params, seed, n_real, device=device, roughness=spectrum)
    psd = _host(psd_rows(lines, params.dx, device))
    expected = roughness.grid_psd(params, spectrum)
    mean, stderr = psd.mean(axis=0), psd.std(axis=0, ddof=1) / math.sqrt(n_real)
    scale = float(np.max(expected))
    deviation = float(np.max(np.abs(mean - expected)) / scale)
    # the RMS scale's spread: the Nyquist mode's share of the mean square (its cos^2 of the phase)
    nyquist_share = 2.0 * params.dq * expected[-1] / np.sum(2.0 * params.dq * expected) if params.n_points % 2 == 0 else 0.0
    within = np.abs(mean - expected) <= Z_SIGMA * stderr + (nyquist_share + 1e-9) * scale
    rms = float(np.sqrt(np.mean(_host(lines) ** 2, axis=1)).mean())
    return {"model": spectrum.describe().get("model"), "max_relative_deviation": deviation,
            "max_relative_stderr": float(np.max(stderr) / scale), "line_rms_m": rms,
            "expected_rms_m": roughness.line_rms(params, spectrum), "passed": bool(np.all(within))}


def db_round_trip(params: Params, wavelengths_mm, levels_db, seed: int = 0, n_real: int = 4,
                  device: str = "cpu") -> dict:
    """dB table -> PSD (:class:`mdroll.roughness.BandLevels`) -> lines -> 1/3-octave levels
    (:func:`bands.roughness_levels` of the lines' mean periodogram), per band that holds a bin of
    the line's grid; passes within :data:`ROUND_TRIP_DB` per band."""
    spectrum = roughness.BandLevels(wavelengths_mm, levels_db, kind="profile", source="round trip")
    lines = rough_lines(params, seed, n_real, device=device, roughness=spectrum)
    psd = _host(psd_rows(lines, params.dx, device)).mean(axis=0)
    q = params.dq * np.arange(psd.size)
    measured_db, counts = bands.roughness_levels(q, psd, params.dq, spectrum.n)
    resolved = counts > 0
    difference = measured_db[resolved] - spectrum.levels_db[resolved]
    return {"wavelength_mm": bands.nominal(spectrum.n[resolved]).tolist(),
            "requested_dB": spectrum.levels_db[resolved].tolist(), "measured_dB": measured_db[resolved].tolist(),
            "bins": counts[resolved].tolist(), "unresolved_wavelength_mm": bands.nominal(spectrum.n[~resolved]).tolist(),
            "max_abs_difference_dB": float(np.max(np.abs(difference))),
            "passed": bool(np.max(np.abs(difference)) <= ROUND_TRIP_DB)}


def measured_profile_check(params: Params, spectrum, length: float, seed: int = 0, segment_length: float = 0.5) -> dict:
    """A synthetic profile of known spectrum (:func:`measured.synthetic_profile`, ``length`` m) through
    the measured-profile path (detrend, Welch, confidence band): the fraction of Welch bins whose
    95 % band holds the known PSD (about 0.95 expected), and the 1/3-octave levels of the Welch
    estimate against the known ones (within 1 dB; Welch's Hann window leaks a little)."""
    long = params.replace(L=length)
    line = measured.synthetic_profile(spectrum, long, seed)
    estimate = measured.welch_psd(measured.make_profile(line, long.dx, "synthetic"), segment_length)
    known = spectrum.mdr_psd(estimate.q)
    usable = (known > 0) & (estimate.q > 8 * physics.TWO_PI / segment_length) & (estimate.q < 0.5 * long.q_max)
    inside = (estimate.lower[usable] <= known[usable]) & (known[usable] <= estimate.upper[usable])
    dq = estimate.q[1] - estimate.q[0]
    n = bands.wavelength_bands_of_grid(8 * physics.TWO_PI / segment_length, 0.5 * long.q_max)
    welch_db, counts = bands.roughness_levels(estimate.q, estimate.psd, dq, n)
    known_db, _ = bands.roughness_levels(estimate.q, known, dq, n)
    ok = (counts >= 4) & np.isfinite(known_db)
    difference = welch_db[ok] - known_db[ok]
    coverage = float(np.mean(inside))
    return {"length_m": length, "segments": estimate.segments, "dof": estimate.dof, "coverage_95": coverage,
            "wavelength_mm": bands.nominal(n[ok]).tolist(), "band_difference_dB": difference.tolist(),
            "max_abs_band_difference_dB": float(np.max(np.abs(difference))),
            "passed": bool(0.88 <= coverage <= 0.995 and np.max(np.abs(difference)) <= 1.0)}


def _modulation_band_ratio(q, measured_psd, stderr, predicted, q_lo, q_hi, a) -> tuple[float, float]:
    """Sum of measured over sum of predicted on whole modulation periods pi/a between q_lo and q_hi,
    and its standard error (bins independent)."""
    period = physics.modulation_period(a)
    top = q_lo + period * math.floor((q_hi - q_lo) / period)
    mask = (q >= q_lo) & (q < top)
    ratio = float(np.sum(measured_psd[mask]) / np.sum(predicted[mask]))
    return ratio, float(np.sqrt(np.sum(stderr[mask] ** 2)) / np.sum(predicted[mask]))


def high_band_check(params: Params, spectrum, q_lo: float, seed: int = 0, n_real: int = 8, device: str = "cpu",
                    allowance: float = 0.03) -> dict:
    """Eq 39 with the model's C_1D (:func:`mdroll.roughness.line_grid.linear_force_psd`) against the exact force
    PSD (periodic, decoupled) on whole modulation periods of [q_lo, 8 q_lo]: the generalization
    of the eq 40 check (physics.md section 7: within about 1 % up to 24 q_min for the power law);
    passes within ``allowance`` + Z_SIGMA standard errors."""
    spec = EnsembleSpec(params, seed=seed, realizations=n_real, boundary="periodic", window=False, roughness=spectrum)
    result = run_specs([spec], device=device)[0]
    predicted = roughness.linear_force_psd(params, spectrum)[: result.q.size]
    ratio, stderr = _modulation_band_ratio(result.q, result.force_psd, result.force_psd_stderr, predicted,
                                           q_lo, 8 * q_lo, params.a)
    return {"model": spectrum.describe().get("model"), "band": [q_lo, 8 * q_lo], "ratio": ratio, "stderr": stderr,
            "tolerance": allowance + Z_SIGMA * stderr, "passed": abs(ratio - 1.0) <= allowance + Z_SIGMA * stderr}


def _low_band(q, q_top, dq):
    return (q >= 2 * dq) & (q <= q_top)


def eq63_study(params: Params, seed: int = 0, n_real: int = 16, device: str = "cpu") -> dict:
    """Eq 62-63 by simulation: the non-linear low-band force of the short-wave roughness against
    the linear force of the long-wave roughness a roll-off adds (docs/roughness.md restates both).

    Roll-off case: the power law of ``params`` (lambda A of eq 50 from h0 on [q_min, q_max]) with a
    hard cut-off (its low band is non-linear only: the plateau of eq 58) and the same law rolled
    off flat below q_r = q_min down to 2 pi / L (:class:`mdroll.roughness.RollOff`). ISO case: the EN ISO
    3095 limit (absolute), and its part shorter than 2 pi / q_min. Ratio = mean low-band force
    PSD (2 dq .. q_min / 8) of the short-wave part over that of the whole spectrum, against eq 63
    (thesis normalization), the project's closed form (physics.md section 7 low band over eq 39),
    and, for ISO, the general closed form ``4 c^2 C_{h^2}(q) / (k_c^2 sinc^2(q a) C_1D(q))``."""
    p = params
    lam_a = p.lambda_A
    top = p.q_min / 8.0  # q a <= pi / 4: sinc^2 >= 0.81, near the q -> 0 limits of eq 58, 62, 63
    hard = roughness.PowerLaw(p.H, p.q_min, p.q_max, prefactor=lam_a)
    rolled = roughness.RollOff(p.H, p.q_min, p.q_max, prefactor=lam_a)
    iso = roughness.iso3095()
    iso_short = roughness.BandLimited(iso, p.q_min)
    cases = [hard, rolled, iso_short, iso]
    specs = [EnsembleSpec(p, seed=seed, realizations=n_real, boundary="periodic", window=False, roughness=s) for s in cases]
    results = run_specs(specs, device=device)
    q = results[0].q
    band = _low_band(q, top, p.dq)
    low = [float(np.mean(r.force_psd[band])) for r in results]
    low_err = [float(np.sqrt(np.sum(r.force_psd_stderr[band] ** 2)) / band.sum()) for r in results]
    c = physics.edge_coefficient(p.E_star, p.R, p.a)

    def predicted_nonlinear(spectrum):
        grid = roughness.grid_psd(p, spectrum)
        return float(np.mean(physics.force_psd_low_band(q[band], grid, p.dq, p.E_star, p.R, p.a)))

    def predicted_linear(spectrum):
        return float(np.mean(roughness.linear_force_psd(p, spectrum)[: q.size][band]))

    eq62 = 4.0 * lam_a * p.E_star**2 * p.a**2 * p.q_min ** (-2.0 * p.H - 1.0)
    eq63 = 1.3 * (physics.THESIS_HURST_OFFSET + p.H) ** 2 / (4.0 * p.H) * (p.h0 / p.d0) ** 2
    closed = p.H / (4.0 * (4.0 * p.H + 1.0)) * (p.h0 / p.d0) ** 2
    rolloff = {
        "measured_ratio": low[0] / low[1],
        "measured_ratio_rel_stderr": math.hypot(low_err[0] / low[0], low_err[1] / low[1]),
        "eq63_thesis": eq63, "closed_form_q0": closed,
        "closed_form_band": predicted_nonlinear(hard) / predicted_linear(rolled),
        "eq63_thesis_at_d_1mm": eq63 * (p.d0 / 1e-3) ** 2,
        "nonlinear_low_band_N2m": low[0], "nonlinear_predicted_N2m": predicted_nonlinear(hard),
        "eq58_thesis_N2m": float(physics.force_psd_plateau_thesis(p.E_star, p.R, p.h0, p.H, p.a, p.q_min)),
        "total_low_band_N2m": low[1], "eq62_N2m": eq62, "eq39_N2m": predicted_linear(rolled),
    }
    iso_nonlinear = predicted_nonlinear(iso_short)
    iso_linear = predicted_linear(iso)
    iso_record = {
        "measured_ratio": low[2] / low[3],
        "measured_ratio_rel_stderr": math.hypot(low_err[2] / low[2], low_err[3] / low[3]),
        "closed_form_band": iso_nonlinear / iso_linear,
        "short_wave_rms_m": roughness.line_rms(p, iso_short), "rms_m": roughness.line_rms(p, iso),
        "nonlinear_low_band_N2m": low[2], "nonlinear_predicted_N2m": iso_nonlinear,
        "total_low_band_N2m": low[3], "eq39_N2m": iso_linear,
    }
    return {"params": p.as_dict(), "d0_m": p.d0, "a_m": p.a, "edge_coefficient": c, "low_band_rad_per_m": [2 * p.dq, top],
            "n_real": n_real, "rolloff": rolloff, "iso3095": iso_record}


def dynamics_study(params: Params, speeds=(10.0, 20.0, 30.0, 40.0), seed: int = 0, n_real: int = 4,
                   device: str = "cpu", algorithm: str = "tree", offsets_db=(0.0, -10.0, -20.0)) -> dict:
    """Coupled (eq 13) against decoupled (section 5.1) for the EN ISO 3095 limit spectrum, shifted by
    each of ``offsets_db`` (0: the limit itself), at each speed: contact loss, force RMS, and the
    acceleration's 1/3-octave levels (dB re 1e-6 m/s^2). The decoupled mode counts as valid when
    no contact is lost and every band that holds at least 3 bins agrees within
    :data:`DECOUPLED_DB`. Same lines in both modes (same seed)."""
    wavelengths, iso_db = tables.iso3095_limit()
    out = []
    for offset, v0 in ((o, v) for o in offsets_db for v in speeds):
        iso = roughness.BandLevels(wavelengths, iso_db + offset, kind="profile", source=f"ISO 3095 limit {offset:+g} dB")
        p = params.replace(v0=float(v0))
        specs = [EnsembleSpec(p, seed=seed, realizations=n_real, algorithm=algorithm, mode=mode, boundary="periodic",
                              window=False, roughness=iso) for mode in ("decoupled", "coupled")]
        decoupled, coupled = run_specs(specs, device=device)
        n = bands.frequency_bands_of_grid(p.dq, p.q_max, p.v0)
        levels = [bands.frequency_levels(r.q, r.accel_psd, p.dq, n, p.v0, "acceleration") for r in (decoupled, coupled)]
        ok = levels[0][1] >= 3
        difference = levels[1][0][ok] - levels[0][0][ok]
        f = bands.nominal(n[ok])
        steps = coupled.steps * coupled.n_real
        worst = int(np.argmax(np.abs(difference)))
        lost = coupled.contact_lost_steps / steps
        out.append({"offset_dB": offset, "line_rms_m": roughness.line_rms(p, iso), "v0": v0, "contact_lost_fraction": lost, "force_rms_coupled_N": coupled.force_rms,
                    "force_rms_decoupled_N": decoupled.force_rms, "frequency_Hz": f.tolist(),
                    "accel_level_decoupled_dB": levels[0][0][ok].tolist(), "accel_level_coupled_dB": levels[1][0][ok].tolist(),
                    "difference_dB": difference.tolist(), "max_abs_difference_dB": float(abs(difference[worst])),
                    "at_Hz": float(f[worst]), "resonance_wavelength_m": p.v0 / (p.omega_0 / physics.TWO_PI),
                    "decoupled_valid": bool(lost == 0 and np.all(np.abs(difference) <= DECOUPLED_DB))})
    return {"params": params.as_dict(), "n_real": n_real, "d0_m": params.d0, "f0_Hz": params.omega_0 / physics.TWO_PI,
            "cases": out}


def contact_filter_study(params: Params, seed: int = 0, n_real: int = 8, device: str = "cpu") -> dict:
    """The MDR contact filter measured from an ensemble (ISO 3095 spectrum, periodic, decoupled):
    ``L_F - L_r - 20 lg(k_c r0 / F0)`` per wavelength band (force and roughness band-integrated
    over the same wavenumbers), beside eq 39 on the same grid bins and the closed band form of
    :func:`filters.mdr_contact_filter`; and the comparison with CNOSSOS-EU A3."""
    iso = roughness.iso3095()
    result = run_specs([EnsembleSpec(params, seed=seed, realizations=n_real, boundary="periodic", window=False, roughness=iso)],
                       device=device)[0]
    grid = roughness.grid_psd(params, iso)
    q = result.q
    n = bands.wavelength_bands_of_grid(params.dq, params.q_max)
    n = n[np.isin(n, iso.n)]
    ms_r, counts = bands.band_mean_squares(q, grid, params.dq, *bands.wavelength_band_edges_q(n))
    ms_f, _ = bands.band_mean_squares(q, result.force_psd, params.dq, *bands.wavelength_band_edges_q(n))
    linear = roughness.linear_force_psd(params, iso)[: q.size]
    ms_lin, _ = bands.band_mean_squares(q, linear, params.dq, *bands.wavelength_band_edges_q(n))
    k_c_db = 20.0 * math.log10(params.k_contact * bands.REFERENCES["roughness"] / bands.REFERENCES["force"])
    roughness_db = bands.level_db(ms_r, bands.REFERENCES["roughness"])
    measured_db = bands.level_db(ms_f, bands.REFERENCES["force"]) - roughness_db - k_c_db
    eq39_db = bands.level_db(ms_lin, bands.REFERENCES["force"]) - roughness_db - k_c_db
    ok = counts >= 3
    return {"params": params.as_dict(), "a_m": params.a, "n_real": n_real, "wavelength_mm": bands.nominal(n[ok]).tolist(),
            "measured_dB": measured_db[ok].tolist(), "eq39_grid_dB": eq39_db[ok].tolist(),
            "closed_band_dB": filters.mdr_contact_filter(n[ok], params.a).tolist(),
            "max_abs_measured_minus_eq39_dB": float(np.max(np.abs(measured_db[ok] - eq39_db[ok]))),
            "cnossos": filters.cnossos_comparison(params)}


def roll_profile(profile: measured.Profile, params: Params, algorithm: str = "tree", device: str = "cpu") -> dict:
    """A measured profile rolled directly as one realization (decoupled, periodic, at d0): its
    force series' PSD (N^2 m) at q (rad/m) and the force RMS (N)."""
    line = measured.profile_line(profile, params)
    force = contact_force(line, params, algorithm=algorithm, boundary="periodic", device=device)
    psd = _host(psd_rows(force, params.dx, device))[0]
    force_host = _host(force)[0]
    return {"q": params.dq * np.arange(psd.size), "force_psd": psd, "force_rms": float(np.std(force_host))}


#: The dB table of the round trip: wavelengths (mm) and levels (dB re 1 um).
ROUND_TRIP_TABLE = ((1000.0, 500.0, 200.0, 100.0, 50.0, 20.0, 10.0, 5.0, 2.0, 1.0),
                    (10.0, 8.0, 3.0, 0.0, -2.0, -5.0, -8.0, -10.0, -12.0, -15.0))


def _lines(s: RailwaySize, seed: int, device: str) -> list:
    p = s.base
    line_models = (roughness.PowerLaw(p.H, p.q_min, p.q_max), roughness.RollOff(p.H, p.q_min, p.q_max),
                   roughness.iso3095(),
                   roughness.PowerLaw(p.H, p.q_min, p.q_max, kind="areal"),
                   roughness.Tabulated(np.geomspace(p.q_min / 4, p.q_max, 50), 1e-20 * np.geomspace(1, 1e-6, 50)),
                   roughness.FromCallable(lambda q: 1e-14 / (1.0 + (q / 2000.0) ** 3), absolute=True))
    return [line_spectrum_check(p, m, seed, 4, device) for m in line_models]


def _round_trip(s: RailwaySize, seed: int, device: str) -> dict:
    p = s.base
    return db_round_trip(p.replace(L=max(p.L, 5.0), dx=max(p.dx, 5e-5)), *ROUND_TRIP_TABLE, seed, 4, device)


def _measured_profile(s: RailwaySize, seed: int, device: str) -> dict:
    p = s.base
    spectrum = roughness.RollOff(p.H, 2 * p.q_min / 5, p.q_max, prefactor=p.lambda_A)
    return measured_profile_check(p.replace(dx=5e-5), spectrum, s.profile_length, seed, 0.25)


def _high_band(s: RailwaySize, seed: int, device: str) -> list:
    p = s.base
    return [high_band_check(p, roughness.PowerLaw(p.H, p.q_min, p.q_max), p.q_min, seed, s.n_real, device),
            high_band_check(p, roughness.RollOff(p.H, p.q_min, p.q_max), p.q_min, seed, s.n_real, device)]


#: The studies of :func:`run_all` by name (``mdroll roughness check --only NAME``), each a function
#: of the rung (:class:`RailwaySize`), the seed and the device.
RAILWAY_STUDIES = Registry("railway study", [
    ("lines", _lines),
    ("round_trip", _round_trip),
    ("measured_profile", _measured_profile),
    ("high_band", _high_band),
    ("eq63", lambda s, seed, device: eq63_study(s.eq63, seed, s.n_real_eq63, device)),
    ("dynamics", lambda s, seed, device: dynamics_study(s.dynamics, s.speeds, seed, max(2, s.n_real // 2), device)),
    ("contact_filter", lambda s, seed, device: contact_filter_study(s.dynamics, seed, max(2, s.n_real // 2), device)),
    ("track", lambda s, seed, device: track_study.track_study(s.track, seed, device)),
])


def run_all(size: str = "quick", seed: int = 0, device: str = "cpu", only=None) -> dict:
    """The studies of :data:`RAILWAY_STUDIES` (``only``: a subset of their names) at ``size`` ("quick" or
    "full"); a JSON-ready record: the provenance (:func:`mdroll.experiments.provenance`) and one
    entry per study."""
    s = SIZES.rung(size)
    record = provenance(device, size, seed, s)
    for name in RAILWAY_STUDIES if only is None else only:
        record[name] = RAILWAY_STUDIES.named(name)(s, seed, device)
    return record
