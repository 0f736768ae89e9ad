"""How good the inversion is: parametric bootstrap, round trips and the study over a grid (its
tables and figure: :mod:`.roundtrip_report`).

A round trip simulates an ensemble with known parameters (:func:`mdroll.run_specs`), inverts
its acceleration spectrum with :func:`mdroll.inverse.fit` and compares. The study runs round
trips over a grid of true parameters (one factor at a time around the thesis's defaults) against
the number of averaged passes K and the rolling distance L, and a realistic measurement (band
20 Hz - 20 kHz, an additive noise floor, a one-sided per-Hz table). Simulations use the open
boundary (the thesis's) with the Hann window of section 6, whose spectra are free of the
leakage a non-periodic series otherwise puts at high q; the fit knows m, R and v0 and fits H,
q_min, a, h0, E* and the nuisance a_jitter (and the noise floor in the realistic case).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from ..arguments import check_integer
from ..devices import cpu_cores
from ..ensemble.spec import EnsembleSpec, run_specs
from ..experiments import Ladder, provenance
from ..errors import ParameterError
from ..params import Params
from ..physics import TWO_PI, effective_modulus
from .correction import iterate, simulation_params
from .fit import fit, refit
from .forward_model import load_times_radius
from .observed import MAX_PASSES, from_result, read_table, write_table

#: Parameters compared in a round trip, and their targets at the thesis's scale (K = 300,
#: L = 5 m): absolute for H, relative for the others.
TARGETS = {"H": 0.02, "a": 0.005, "q_min": 0.01, "h0": 0.03, "E_star": 0.02}
KNOWN = ("m", "R")
#: Seed of the first realistic case (one per repeat: 7, 8, ...).
REALISTIC_SEED = 7


@dataclass(frozen=True)
class RoundTripSize:
    """The study's parameters on one rung of the ladder (:data:`SIZES`): the true parameter sets, passes K, lengths L (m), repeats (seeds) per cell and per
    realistic case, the realistic cases' speeds (m/s), and the (K, L) of those."""

    truths: tuple
    passes: tuple
    lengths: tuple
    repeats: int
    realistic_speeds: tuple
    realistic_passes: int
    realistic_length: float


def truth_grid(full: bool) -> tuple:
    """One factor at a time around the defaults: H 0.3-0.9, h0 0.2-2 um, q_min over a decade,
    a 3-8 mm (through F_N at R = 0.5 m, eq 14-15), v0 5-40 m/s."""
    base = {}
    a_loads = {3e-3: None, 8e-3: None}
    for a in a_loads:  # F_N that gives the contact radius a at the default E*, R (eq 14-15)
        a_loads[a] = load_times_radius(a, effective_modulus(210e9, 0.3)) / 0.5
    if full:
        variations = ([{"H": h} for h in (0.3, 0.5, 0.9)] + [{"h0": h} for h in (0.2e-6, 2e-6)]
                      + [{"q_min": TWO_PI / w} for w in (10e-3, 2e-3, 1e-3)] + [{"F_N": f} for f in a_loads.values()]
                      + [{"v0": v} for v in (5.0, 20.0, 40.0)])
    else:
        variations = [{"H": 0.4}, {"H": 0.9}, {"h0": 0.2e-6}, {"q_min": TWO_PI / 10e-3}, {"F_N": a_loads[3e-3]},
                      {"v0": 40.0}]
    return tuple([base] + variations)


SIZES = Ladder(
    quick=RoundTripSize(truths=truth_grid(False), passes=(1, 10, 100), lengths=(0.5, 1.0), repeats=1,
                        realistic_speeds=(10.0, 20.0, 40.0), realistic_passes=100, realistic_length=1.0),
    full=RoundTripSize(truths=truth_grid(True), passes=(1, 10, 100, 300), lengths=(0.5, 1.0, 5.0), repeats=3,
                       realistic_speeds=(10.0, 20.0, 40.0), realistic_passes=300, realistic_length=5.0),
)


#: The most bootstrap replicates (each an ensemble and a fit): beyond, the percentiles do not move.
MAX_BOOTSTRAP = 10_000
#: The most seeds per true parameter set a round trip runs.
MAX_REPEATS = 1_000


def check_replicates(replicates) -> int:
    """``replicates`` if it is a bootstrap's count (2 .. :data:`MAX_BOOTSTRAP`), else a ParameterError."""
    if isinstance(replicates, bool) or not isinstance(replicates, int) or not 2 <= replicates <= MAX_BOOTSTRAP:
        raise ParameterError(f"bootstrap = {replicates!r} is not allowed: it needs 2 to {MAX_BOOTSTRAP} replicates")
    return replicates


def bootstrap(spectrum, result, replicates: int, device: str = "auto", seed: int = 1_000_003, bin: int = 1,
              runner=None) -> dict:
    """Parametric bootstrap: simulate ``replicates`` ensembles with mdroll at the estimate (K passes
    each, the spectrum's own L, dx, boundary and window; seeds ``seed + i``) through
    :func:`mdroll.run_specs`, refit each like the original, and report per free parameter the
    replicates' estimates, their 2.5 and 97.5 percentiles (the percentile interval ``ci95``),
    their mean less the simulated value (the estimator's ``bias`` there), the estimate less that
    bias (``bias_corrected``) and the basic interval ``ci95_basic`` (the percentiles reflected
    about the simulated value and shifted to the estimate), which covers when the bias is the
    same at the truth. Only for mdroll spectra (the simulation's L, dx and boundary are needed).
    ``runner``: where the replicates' ensembles run (``run_specs(..., runner=)``, e.g. a
    :class:`mdroll.distributed.DaskRunner`); None: in this process on ``device``."""
    check_replicates(replicates)
    sim = spectrum.simulation
    if not sim:
        raise ParameterError("the bootstrap simulates at the estimate and needs the simulation's L and dx: it is "
                             "available for mdroll spectra only")
    params = simulation_params({**result.estimates, "v0": result.known["v0"]}, sim)
    specs = [EnsembleSpec(params, seed=seed + i, realizations=result.passes, boundary=sim["boundary"],
                          mode=sim["mode"], algorithm=sim["algorithm"], window=spectrum.window)
             for i in range(replicates)]
    start = {n: result.estimates[n] for n in result.free}
    estimates = {n: [] for n in result.free}
    for ensemble in run_specs(specs, device=device, runner=runner):
        refit = fit(from_result(ensemble, spectrum.quantity, spectrum.window), known=result.known, free=result.free,
                    band=result.band, passes=result.passes, bin=bin, start=start, profile=False,
                    correction=result.correction_used or "none", fill_check="off")
        for n in result.free:
            estimates[n].append(refit.estimates[n])
    centre = {n: result.estimates[n] for n in estimates}
    if "q_min" in centre:  # the simulation's q_min is the grid's (see simulation_params)
        centre["q_min"] = params.q_min
    bias = {n: float(np.mean(v)) - centre[n] for n, v in estimates.items()}
    ci = {n: [float(np.percentile(v, 2.5)), float(np.percentile(v, 97.5))] for n, v in estimates.items()}
    return {"replicates": replicates, "seed": seed, "params": params.as_dict(), "estimates": estimates,
            "bias": bias, "ci95": ci,
            "bias_corrected": {n: result.estimates[n] - bias[n] for n in estimates},
            "ci95_basic": {n: [result.estimates[n] - (hi - centre[n]), result.estimates[n] - (lo - centre[n])]
                           for n, (lo, hi) in ci.items()}}


def _round_trip_spec(truth: Params, passes: int, seed: int, boundary: str = "open", window: bool = True):
    return EnsembleSpec(truth, seed=seed, realizations=passes, boundary=boundary, window=window)


def round_trip(truth: Params, passes: int, seed: int = 0, device: str = "auto", known=KNOWN, band=None,
               bin: int = 1, boundary: str = "open", window: bool = True, correction: str = "simulated") -> dict:
    """Simulate ``passes`` realizations at ``truth`` (decoupled; open boundary with the Hann window
    unless told otherwise), invert the acceleration spectrum knowing ``known`` (and v0) with the
    ``correction`` ("simulated" or "none", :func:`~mdroll.inverse.fit`), compare.
    Returns one row: the estimates, their 95 % intervals, errors (H absolute, others relative)
    and whether each interval covers."""
    t0 = time.perf_counter()
    ensemble = run_specs([_round_trip_spec(truth, passes, seed, boundary, window)], device=device)[0]
    spectrum = from_result(ensemble, "accel", window=window)
    t1 = time.perf_counter()
    result = fit(spectrum, known={k: getattr(truth, k) for k in known}, band=band, bin=bin, profile=False,
                 correction=correction, device=device)
    return _compare(result, spectrum.truth, {"passes": passes, "L": truth.L, "seed": seed, "simulate_s": t1 - t0,
                                             "fit_s": time.perf_counter() - t1})


def _closed_form_fit(job):
    """The closed form's fit of one simulated spectrum (a top-level function: worker processes run it)."""
    spectrum, known = job
    return fit(spectrum, known=known, profile=False, correction="none")


def _compare(result, truth: dict, row: dict) -> dict:
    """One row of the study: estimates, 95 % intervals, errors (H absolute, others relative), whether
    each interval covers; with a correction also the closed form's errors and the iterations."""
    row = dict(row, truth={n: truth[n] for n in TARGETS if n in truth}, estimates={}, ci95={}, error={}, covered={},
               gof={k: result.gof[k] for k in ("deviance_per_dof", "phi", "tau", "ks_p")}, success=result.success,
               message=result.message)
    for name in TARGETS:
        if name not in result.free:
            continue
        value, lo, hi, true = result.estimates[name], *result.ci95[name], truth[name]
        row["estimates"][name] = value
        row["ci95"][name] = [lo, hi]
        row["error"][name] = _relative(name, value, true)
        row["covered"][name] = bool(lo <= true <= hi)
    if result.correction:
        first = result.correction["iterates"][0]
        row["error_closed_form"] = {n: _relative(n, first[n], truth[n]) for n in row["error"]}
        row["iterations"] = len(result.correction["iterates"]) - ("ratio" not in result.correction)
        row["converged"] = result.correction["converged"]
        row["correction_ratio"] = result.correction.get("ratio")
        row["correction_skipped"] = result.correction.get("skipped")
    if result.discrepancy:
        d = result.discrepancy
        row["discrepancy"] = {"level": d["level"], "tilt": d["tilt"], "widening": {n: d["widening"][n] for n in row["error"]},
                              "covered_without": {n: bool(lo <= truth[n] <= hi) for n, (lo, hi) in d["ci95_without"].items()
                                                  if n in row["error"]}}
    if result.fill_check:
        check = result.fill_check
        row["fill_check"] = {"a_jitter_fitted": check["a_jitter_fitted"], "a_jitter_edge": check["a_jitter_edge"],
                             "widening": {n: check["widening"][n] for n in row["error"]},
                             "covered_local": {n: bool(lo <= truth[n] <= hi) for n, (lo, hi) in check["ci95_local"].items()
                                               if n in row["error"]}}
    return row


def _relative(name: str, value: float, truth: float) -> float:
    return value - truth if name == "H" else value / truth - 1.0


def realistic_case(truth: Params, passes: int, seed: int, device: str, folder, noise_fraction: float = 0.3,
                   correction: str = "none", discrepancy=None) -> dict:
    """A measurement: the simulated acceleration spectrum as a one-sided per-Hz CSV table over 20 Hz -
    20 kHz, plus a white noise floor of ``noise_fraction`` times the PSD's mean over the top tenth
    of that band (each bin's noise a chi-square of 2K degrees of freedom), read back with
    :func:`~mdroll.inverse.read_table` and fitted with the floor free (continuous response, eq 50's
    continuum normalization: the table does not carry dt or L). ``correction``: "none" (a table's
    default, and the study's: with the noise floor free the simulated one moves H the wrong way,
    docs/inverse.md) or "simulated", for which the table is given the simulation's settings (L,
    dx, nu: what the correction's ensembles need), which moved H by +0.010 to +0.089 (docs/inverse.md).
    ``discrepancy``: :func:`~mdroll.inverse.fit`'s (None: its default, :data:`~mdroll.inverse.fit.DISCREPANCY`
    for the closed form)."""
    spec = EnsembleSpec(truth, seed=seed, realizations=passes, boundary="open", window=True)
    ensemble = run_specs([spec], device=device)[0]
    spectrum = from_result(ensemble, "accel", window=True)
    band = (TWO_PI * 20.0, TWO_PI * 20e3)
    inside = (spectrum.omega >= band[0]) & (spectrum.omega <= band[1])
    floor = noise_fraction * float(np.mean(spectrum.psd[inside][-max(1, inside.sum() // 10):]))
    rng = np.random.default_rng([seed, passes, 19])
    noisy = spectrum.psd[inside] + floor * rng.chisquare(2 * passes, inside.sum()) / (2 * passes)
    measured = type(spectrum)(omega=spectrum.omega[inside], psd=noisy, quantity="accel", passes=passes,
                              window=True, source="realistic")
    path = write_table(measured, folder / f"realistic_v{truth.v0:g}_s{seed}.csv", frequency_unit="Hz", sided="one",
                       density="Hz")
    table = read_table(path, quantity="accel", frequency_unit="Hz", sided="one", density="Hz", passes=passes, window=True)
    if correction == "simulated":  # a measurement's rolling distance and the model's dx and nu are known
        table = dataclasses.replace(table, simulation=spectrum.simulation)
    t1 = time.perf_counter()
    result = fit(table, known={"m": truth.m, "R": truth.R, "v0": truth.v0},
                 free=["H", "q_min", "a", "h0", "E_star", "a_jitter", "noise"], profile=False, correction=correction,
                 device=device, discrepancy=discrepancy)
    return _compare(result, spectrum.truth, {"passes": passes, "L": truth.L, "v0": truth.v0, "seed": seed,
                                             "noise_floor": floor, "fit_s": time.perf_counter() - t1})


def check_study_counts(workers=1, passes=None, correction_passes=None, repeats=None, lengths=None) -> None:
    """:func:`run_study`'s counts, each bounded (a ParameterError naming it and its range):
    ``workers`` at most the cores this process may use, ``passes`` (each) and ``correction_passes``
    at most :data:`~mdroll.inverse.observed.MAX_PASSES`, ``repeats`` at most :data:`MAX_REPEATS`;
    and ``lengths``, each a line that :class:`~mdroll.params.Params` allows."""
    check_integer("workers", workers, 1, "processes", cpu_cores())
    for length in lengths or ():
        Params(L=length)
    for k in passes or ():
        check_integer("passes", k, 1, "passes", MAX_PASSES)
    if correction_passes is not None:
        check_integer("correction_passes", correction_passes, 1, "passes", MAX_PASSES)
    if repeats is not None:
        check_integer("repeats", repeats, 1, "seeds per truth", MAX_REPEATS)


def run_study(size: str = "quick", device: str = "auto", folder=None, progress=lambda text: None, workers: int = 1,
              passes=None, lengths=None, correction: str = "simulated", repeats: int | None = None,
              correction_passes: int | None = None, realistic_only: bool = False) -> dict:
    """Every round trip of ``SIZES[size]`` (``passes`` and ``lengths`` restrict its K and L, ``repeats``
    replaces its seeds per truth), fitted with the ``correction`` ("simulated" or "none"; its
    ensembles of ``correction_passes`` passes, default
    :func:`mdroll.inverse.correction.default_passes`) and the
    realistic cases; a JSON-ready record with the provenance (:func:`mdroll.experiments.provenance`),
    the rows, a summary per (K, L) (median and 90th percentile of |error|, coverage of the 95 %
    intervals) and the total time.

    Per (K, L) cell the ensembles run one after the other on ``device`` (:func:`mdroll.run_specs`),
    then their fits in ``workers`` processes (the fit is NumPy on the host). The realistic cases
    run when the plan's (K, L) for them is among the cells; ``realistic_only``: they alone."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor
    from pathlib import Path

    plan = SIZES.rung(size)
    if correction not in ("simulated", "none"):
        raise ParameterError(f"correction = {correction!r} is not allowed: use 'simulated' or 'none'")
    check_study_counts(workers, passes, correction_passes, repeats, lengths)
    if repeats is not None:
        plan = dataclasses.replace(plan, repeats=repeats)
    cells_k = tuple(plan.passes if passes is None else passes)
    cells_l = tuple(plan.lengths if lengths is None else lengths)
    folder = Path(folder or ".")
    started = time.perf_counter()
    rows = []
    # spawned, not forked: the parent may hold a CUDA context by the time the workers start
    pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) if workers > 1 else None
    try:
        for length in () if realistic_only else cells_l:
            for k in cells_k:
                plan_rows = [(index, change, repeat) for index, change in enumerate(plan.truths)
                             for repeat in range(plan.repeats)]
                truths = [Params(L=length, **change) for _, change, _ in plan_rows]
                seeds = [1000 * index + repeat for index, _, repeat in plan_rows]
                t0 = time.perf_counter()
                ensembles = run_specs([_round_trip_spec(t, k, s) for t, s in zip(truths, seeds)], device=device)
                simulate_s = (time.perf_counter() - t0) / len(ensembles)
                spectra = [from_result(e, "accel", window=True) for e in ensembles]
                del ensembles
                mapper = pool.map if pool else map
                t1 = time.perf_counter()
                results = list(mapper(_closed_form_fit, [(s, {n: getattr(t, n) for n in KNOWN})
                                                         for s, t in zip(spectra, truths)]))
                if correction == "simulated":
                    results = iterate(spectra, results, refit=lambda jobs: list(mapper(refit, jobs)),
                                      simulate=lambda specs: run_specs(specs, device=device),
                                      passes=correction_passes)
                fit_s = (time.perf_counter() - t1) / len(results)
                for (index, change, repeat), seed, spectrum, result in zip(plan_rows, seeds, spectra, results):
                    row = _compare(result, spectrum.truth, {"passes": k, "L": length, "change": change, "seed": seed,
                                                            "simulate_s": simulate_s, "fit_s": fit_s})
                    rows.append(row)
                    progress(f"K={k} L={length} {change or 'defaults'} seed {seed}: "
                             + " ".join(f"{n} {format_error(n, e)}" for n, e in row["error"].items())
                             + (f" ({row['iterations']} iterations)" if "iterations" in row else ""))
    finally:
        if pool:
            pool.shutdown()
    realistic = []
    if plan.realistic_length in cells_l and plan.realistic_passes in cells_k:
        for v0 in plan.realistic_speeds:
            truth = Params(L=plan.realistic_length, v0=v0)
            for seed in range(REALISTIC_SEED, REALISTIC_SEED + plan.repeats):
                row = realistic_case(truth, plan.realistic_passes, seed=seed, device=device, folder=folder)
                realistic.append(row)
                progress(f"realistic v0={v0} seed {seed}: "
                         + " ".join(f"{n} {format_error(n, e)}" for n, e in row["error"].items()))
    return {**provenance(device, size, None, plan), "rows": rows, "summary": summarize(rows), "realistic": realistic,
            "targets": TARGETS,
            "known": list(KNOWN) + ["v0"], "workers": workers, "correction": correction,
            "seconds": time.perf_counter() - started}


def format_error(name: str, error: float) -> str:
    """An error as text: H absolute, the others in per cent."""
    return f"{error:+.4f}" if name == "H" else f"{100 * error:+.2f}%"


def summarize(rows) -> list:
    """Per (K, L): for each parameter the median and 90th percentile of |error| and the fraction of
    round trips whose 95 % interval covers the truth."""
    out = []
    for key in sorted({(r["passes"], r["L"]) for r in rows}):
        cell = [r for r in rows if (r["passes"], r["L"]) == key]
        entry = {"passes": key[0], "L": key[1], "round_trips": len(cell)}
        for name in TARGETS:
            errors = np.array([abs(r["error"][name]) for r in cell if name in r["error"]])
            covered = [r["covered"][name] for r in cell if name in r["covered"]]
            if errors.size:
                entry[name] = {"median_abs_error": float(np.median(errors)),
                               "p90_abs_error": float(np.percentile(errors, 90)),
                               "coverage": float(np.mean(covered))}
        out.append(entry)
    return out
