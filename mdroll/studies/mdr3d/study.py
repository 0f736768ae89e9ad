"""``mdroll study mdr-vs-3d``: is the MDR right for a wheel rolling on rough rails? Its force
spectrum against the 3-D boundary-element reference (:mod:`mdroll.bem`) on the same problems,
band by band, and the contact filters of both and of the distributed point-reacting spring (DPRS)
model of Remington & Webb (:mod:`mdroll.bem.dprs`) beside CNOSSOS-EU's A3 (docs/mdr-vs-3d.md).

Per indenter (:data:`~.problems.INDENTERS`) every case of the rung (surface x H x h0/d0 x
q_min a) rolls in one batch of the 3-D solver (realizations ``0 .. R-1`` of each case at the
study's seed), and each MDR variant (:data:`~.problems.VARIANTS`) and the DPRS bed roll over the
same positions. Claims, one per (surface, indenter, model, band) at the smallest h0/d0 (the linear
regime), averaged over H and q_min: the model's band power (the DPRS's over its own stiffness)
equals the 3-D one within 1 dB. Every case's
ratios with their 95 % intervals, the measured contact filters and the closed forms of
:mod:`.linear` are in the measurements.
"""

from __future__ import annotations

import itertools
import math
import time

import numpy as np

from ... import physics
from ...devices import array_module
from ...roughness import tables
from ...roughness.bands import band_centres, band_numbers
from ...experiments import markdown_table
from ..core import Claim, StudyOutcome
from . import compare, linear, problems
from .figures import figures

#: Steel (physics.md section 1): E* of eq 1-2.
E_STAR = physics.effective_modulus(210e9, problems.NU)
#: The band agreement asked of the MDR (dB).
ALLOWANCE_DB = 1.0
#: Shortest wavelength compared, in cells: the contact's pressure is resolved on 4 cells a wave.
CELLS_PER_WAVE = 4.0


def cases(surfaces, indenter, hursts, ratios, qmin_as, anisotropy) -> list:
    """The :class:`~.problems.Case` of one indenter, in the order of the batch."""
    return [problems.Case(s, indenter, H, r, q, anisotropy)
            for s, H, r, q in itertools.product(surfaces, hursts, ratios, qmin_as)]


def a3_case(load: float, wheel_radius: float):
    """CNOSSOS-EU's A3 (wavelength bands, dB) for (load, wheel diameter), or None if not tabulated."""
    wavelengths, a3 = tables.cnossos_a3()
    for (case_load, diameter), values in a3.items():
        if math.isclose(case_load, load) and math.isclose(diameter, 2.0 * wheel_radius):
            return band_numbers(wavelengths), values
    return None


def _compare_case(shape, mesh, case, bem, profile, mdr_runs, dprs_force, device) -> dict:
    """Band ratios (every variant, and the DPRS bed's) and measured filters of one case."""
    q, bem_psd = compare.psds(bem, mesh.dx, device)
    q_min = case.qmin_a / shape.semi_x
    q_top = math.pi / (CELLS_PER_WAVE / 2.0 * mesh.dx)
    out = {"case": case.__dict__, "label": case.label(), "bem_force_rms_N": float(bem.std(axis=1).mean()),
           "variants": {}}
    _, rough_psd = compare.psds(profile, mesh.dx, device)
    bands = compare.filter_bands(q, q_min, q_top)
    out["filter"] = {"bands": bands.tolist(),
                     "3d": compare.measured_filter(q, bem_psd, rough_psd, shape.stiffness, bands)}
    for variant, force in mdr_runs.items():
        _, psd = compare.psds(force, mesh.dx, device)
        radius = shape.semi_x if variant == "corrected" else math.sqrt(shape.radius_x * shape.mdr_approach)
        stiffness = shape.stiffness if variant == "corrected" else 2.0 * E_STAR * radius
        paired = variant != "mdr" or case.surface == "a"
        masks = compare.masks(q, q_min, q_top, shape.semi_x, radius)
        out["variants"][variant] = {name: compare.band_ratio(psd, bem_psd, masks[name], paired)
                                    for name in compare.BANDS}
        out["variants"][variant]["periods"] = compare.period_ratios(psd, bem_psd, q, q_min, q_top, shape.semi_x, paired)
        out["variants"][variant]["force_rms_N"] = float(force.std(axis=1).mean())
        out["filter"][variant] = compare.measured_filter(q, psd, rough_psd, stiffness, bands)
    stiffness = problems.bed(shape).stiffness
    _, psd = compare.psds(dprs_force, mesh.dx, device)
    out["filter"]["dprs"] = compare.measured_filter(q, psd, rough_psd, stiffness, bands)
    psd = psd * (shape.stiffness / stiffness) ** 2  # each force over its own stiffness: the filters' ratio
    masks = compare.masks(q, q_min, q_top, shape.semi_x, shape.semi_x)  # dips: the 3-D's own zeros
    out["dprs"] = {name: compare.band_ratio(psd, bem_psd, masks[name], True) for name in compare.BANDS}
    out["dprs"]["periods"] = compare.period_ratios(psd, bem_psd, q, q_min, q_top, shape.semi_x, True)
    out["dprs"]["force_rms_N"] = float(dprs_force.std(axis=1).mean())
    return out


def _run_indenter(name, rung, seed, device, progress) -> dict:
    """Every case of indenter ``name``: the 3-D rolling batch, the MDR variants, the comparisons."""
    shape = problems.geometry(name, rung["wheel_radius"], rung["crown_radius"], rung["load"], E_STAR)
    mesh = problems.grid(shape, rung["cells"], rung["positions"], min(rung["qmin_as"]) / shape.semi_x)
    todo = cases(rung["surfaces"], name, rung["hursts"], rung["ratios"], rung["qmin_as"], rung["anisotropy"])
    indices = range(rung["realizations"])
    start = time.perf_counter()
    heights = [problems.surfaces(shape, mesh, case, seed, indices, device) for case in todo]
    batch = array_module(heights[0]).concatenate(heights)
    bem, iterations, converged = problems.bem_forces(shape, mesh, batch, device, rung["tol"])
    bem_seconds = time.perf_counter() - start
    dprs_force = problems.dprs_forces(shape, mesh, batch, device)
    dprs_seconds = time.perf_counter() - start - bem_seconds
    del batch
    results = []
    for i, (case, surface) in enumerate(zip(todo, heights)):
        runs = {v: problems.mdr_forces(shape, mesh, case, problems.variant_lines(shape, mesh, case, surface, seed,
                                                                                  indices, v, device), v, device)
                for v in problems.VARIANTS}
        block = slice(i * len(indices), (i + 1) * len(indices))
        results.append(_compare_case(shape, mesh, case, bem[block], problems.centre_profiles(mesh, surface), runs,
                                     dprs_force[block], device))
        if progress:
            print(f"mdr-vs-3d: {case.label()} done", flush=True)
    return {"geometry": shape.as_dict(), "grid": mesh.as_dict(), "cases": results, "bem_seconds": bem_seconds,
            "bem_iterations_mean": float(np.mean(iterations)), "bem_converged": bool(np.all(converged)),
            "seconds": time.perf_counter() - start, "dprs_bed": problems.bed(shape).as_dict(),
            "dprs_seconds": dprs_seconds}


def closed_forms(runs: dict, rung: dict) -> dict:
    """The linear filters (:mod:`.linear`) on each indenter's measured bands (isotropic and
    anisotropic power laws at H of the first case, and a corrugation), and the five CNOSSOS-EU
    A3 cases against the MDR's eq 39 and the 3-D ellipse of the crown radius."""
    out = {}
    H = rung["hursts"][0]
    for name, run in runs.items():
        shape = run["geometry"]
        bands = max((c["filter"]["bands"] for c in run["cases"]), key=len)
        kw = {"q_min": min(rung["qmin_as"]) / shape["semi_x"]}
        mdr_radius = math.sqrt(shape["radius_x"] * shape["mdr_approach"])
        entry = {"bands": bands, "H": H}
        for surface, extra in (("a", {"corrugation": True}), ("b", {}), ("c", {"anisotropy": rung["anisotropy"]})):
            entry[surface] = {model: linear.contact_filter(model, bands, shape["semi_x"], shape["semi_y"], H,
                                                           radius_line=mdr_radius if model == "line" else None,
                                                           **kw, **extra).tolist()
                              for model in linear.MODELS}
        a3 = a3_case(rung["load"], rung["wheel_radius"])
        if a3 is not None:
            lookup = dict(zip(a3[0].tolist(), a3[1].tolist()))
            entry["A3"] = [lookup.get(b) for b in bands]
        out[name] = entry
    out["cnossos"] = cnossos_cases(rung["crown_radius"], H)
    return out


def cnossos_cases(crown_radius: float, H: float) -> list:
    """Per A3 case (load, wheel diameter): A3, the MDR's eq 39 (sphere of the wheel radius), and
    the linear 3-D and DPRS filters of the wheel-by-crown ellipse on a corrugation and on
    isotropic roughness of Hurst exponent H, each in A3's bands (dB)."""
    wavelengths, a3 = tables.cnossos_a3()
    bands = band_numbers(wavelengths)
    rows = []
    for (load, diameter), values in a3.items():
        shape = problems.geometry("ellipse", diameter / 2.0, crown_radius, load, E_STAR)
        mdr_radius = math.sqrt(shape.radius_x * shape.mdr_approach)
        rows.append({"load_N": load, "diameter_m": diameter, "A3_dB": values.tolist(),
                     "MDR_dB": linear.contact_filter("line", bands, shape.semi_x, shape.semi_y, H, corrugation=True,
                                                     radius_line=mdr_radius).tolist(),
                     "3d_corrugation_dB": linear.contact_filter("3d", bands, shape.semi_x, shape.semi_y, H,
                                                                corrugation=True).tolist(),
                     "3d_isotropic_dB": linear.contact_filter("3d", bands, shape.semi_x, shape.semi_y, H).tolist(),
                     "dprs_corrugation_dB": linear.contact_filter("dprs", bands, shape.semi_x, shape.semi_y, H,
                                                                  corrugation=True).tolist(),
                     "dprs_isotropic_dB": linear.contact_filter("dprs", bands, shape.semi_x, shape.semi_y, H).tolist()})
    return {"wavelength_mm": wavelengths.tolist(), "cases": rows}


#: Why a claim of the MDR against the 3-D reference is expected to fail (docs/mdr-vs-3d.md).
KNOWN = {
    "across": "a line cannot average the roughness across the contact width as the 3-D contact does; "
              "Geike's line also carries pi q C_2D, above the profile a trolley measures",
    "lateral mean": "a uniform lateral mean removes short lateral waves faster than the 3-D contact, "
                    "whose flat-punch weight is singular at the edge",
    "low": "below q_min the force is non-linear on a corrugation (the 3-D second-order force exceeds eq 48's "
           "edge term) and linear on (b), (c) through lateral waves that a line misses or overstates",
    "patch": "today's MDR sphere carries the load but has neither the Hertz ellipse's length nor its stiffness",
    "filter": "few bins a band and one centre line as the roughness reference: the measured filter scatters",
    "dprs": "the springs average the roughness uniformly over the patch, 2 J1(rho)/rho, where the elastic contact "
            "weights it by the flat-punch pressure, singular at the edge, sinc(rho): the bed's filter lies above "
            "the 3-D's at the knee (first zero at rho = 3.83, not pi) and falls as rho^-3, not rho^-2, beyond",
    "dprs low": "below q_min on a corrugation the force is second order in the roughness, set at the contact's "
                "edge, where independent springs are not the elastic contact's coupled edge",
    "dprs lateral": "below q_min on (b), (c) the force is linear through lateral waves, which the springs average "
                    "uniformly across the patch (2 J1 of q_y a_y) and the elastic contact with the flat-punch weight",
}
#: The models compared with the 3-D reference: the MDR variants and the DPRS bed.
MODELS = problems.VARIANTS + ("dprs",)
#: Ranges of q a_x of the measured filters' bands (:func:`filter_table`): long waves, the knee, short waves.
FILTER_RANGES = (("q a_x < 1", 0.0, 1.0), ("1 <= q a_x < pi", 1.0, math.pi), ("q a_x >= pi", math.pi, math.inf))


def known(surface: str, indenter: str, variant: str, band: str) -> str:
    """The explanation of :data:`KNOWN` that applies to a claim, or ""."""
    if variant == "dprs":
        return KNOWN["dprs"] if band != "low" else KNOWN["dprs low"] if surface == "a" else KNOWN["dprs lateral"]
    if band == "low":
        return KNOWN["low"]
    if surface != "a":
        return KNOWN["lateral mean"] if variant == "corrected" else KNOWN["across"]
    return KNOWN["patch"] if indenter == "ellipse" and variant != "corrected" else ""


def ratios_of(case: dict, model: str) -> dict:
    """The band ratios over the 3-D force of ``model`` (an MDR variant, or "dprs") in a case."""
    return case["dprs"] if model == "dprs" else case["variants"][model]


def _pooled(entries) -> tuple[np.ndarray, float]:
    """The dB values of band-ratio entries and the standard error of their mean (dB)."""
    values = np.array([e["dB"] for e in entries])
    errors = np.array([10.0 / math.log(10.0) * e["rel_stderr"] for e in entries])
    return values, float(math.sqrt(np.sum(errors**2)) / values.size)


def claims_of(runs: dict, rung: dict) -> list:
    """One claim per (surface, indenter, model, band) at the smallest h0/d0: the mean dB over
    the cases (H, q_min) against 0 within :data:`ALLOWANCE_DB` (the DPRS force over its own
    stiffness against the 3-D force over its own); and per (surface, indenter) the linear closed
    forms of the 3-D and the DPRS filters (:mod:`.linear`) against the measured ones, in the bands
    outside the dips (closed form above -15 dB) of the smallest h0/d0 and q_min."""
    smallest = min(rung["ratios"])
    claims = []
    for name, run in runs.items():
        linear_cases = [c for c in run["cases"] if c["case"]["h0_d0"] == smallest]
        for surface, model, band in itertools.product(rung["surfaces"], MODELS, compare.BANDS):
            found = [ratios_of(c, model)[band] for c in linear_cases
                     if c["case"]["surface"] == surface and ratios_of(c, model)[band]["dB"] is not None]
            if not found:
                continue
            values, stderr = _pooled(found)
            what = "DPRS" if model == "dprs" else f"MDR {model}"
            claims.append(Claim(
                name=f"({surface}) {name} {model} {band}",
                thesis=f"{what} {band}-band force PSD equals the 3-D one (sec 7.1)",
                measured=float(values.mean()), stderr=stderr, expected=0.0, unit="dB", source="3-D reference",
                allowance=ALLOWANCE_DB, known=known(surface, name, model, band),
                note=f"h0/d0 {smallest:g}; {values.size} cases, {values.min():+.2f} to {values.max():+.2f} dB"))
        for surface, model in itertools.product(rung["surfaces"], ("3d", "dprs")):
            chosen = [c for c in linear_cases if c["case"]["surface"] == surface]
            if not chosen:
                continue
            case = min(chosen, key=lambda c: c["case"]["qmin_a"])
            closed = dict(zip(run["closed"]["bands"], run["closed"][surface][model]))
            diff = np.array([m - closed[b] for b, m in zip(case["filter"]["bands"], case["filter"][model])
                             if closed.get(b) is not None and closed[b] > -15.0 and math.isfinite(m)])
            if diff.size < 2:
                continue
            label = "3-D" if model == "3d" else "DPRS"
            claims.append(Claim(
                name=f"({surface}) {name} linear {label} filter",
                thesis=f"the linear 2-D contact filter is the {label} one",
                measured=float(diff.mean()), stderr=float(diff.std(ddof=1) / math.sqrt(diff.size)), expected=0.0,
                unit="dB", source="closed form", allowance=ALLOWANCE_DB,
                known=KNOWN["filter"] if surface != "a" else "",
                note=f"{case['label']}; {diff.size} bands, {diff.min():+.2f} to {diff.max():+.2f} dB"))
    return claims


def verdict_table(runs: dict, rung: dict) -> list:
    """Markdown lines: per (surface, indenter, model, h0/d0) the mean model-to-3-D ratio (dB) of
    each band over the cases (H, q_min), with its range, and whether every case lies within
    :data:`ALLOWANCE_DB` (its 95 % interval included)."""
    rows = []
    for name, run in runs.items():
        for surface, model, ratio in itertools.product(rung["surfaces"], MODELS, rung["ratios"]):
            cells, trusted = [], True
            for band in compare.BANDS:
                found = [ratios_of(c, model)[band] for c in run["cases"] if c["case"]["surface"] == surface
                         and c["case"]["h0_d0"] == ratio and ratios_of(c, model)[band]["dB"] is not None]
                if not found:
                    cells.append("-")
                    continue
                values = [f["dB"] for f in found]
                trusted &= all(-ALLOWANCE_DB <= f["ci95_dB"][0] and f["ci95_dB"][1] <= ALLOWANCE_DB for f in found)
                cells.append(f"{np.mean(values):+.1f} ({min(values):+.1f} to {max(values):+.1f})")
            rows.append((f"({surface})", name, model, f"{ratio:g}", *cells, "yes" if trusted else "no"))
    return markdown_table(("surface", "indenter", "MDR", "h0/d0", "low (dB)", "high (dB)", "dips (dB)",
                           f"all within {ALLOWANCE_DB:g} dB"), rows)


def filter_table(runs: dict, rung: dict) -> list:
    """Markdown lines: per (surface, indenter, model) at the smallest h0/d0 the measured contact
    filter minus the measured 3-D one in the 1/3-octave bands of each range of
    :data:`FILTER_RANGES` (band centre's q a_x), over every case (H, q_min) and band: the mean
    (dB), its range, and the bands within :data:`ALLOWANCE_DB`."""
    smallest = min(rung["ratios"])
    rows = []
    for name, run in runs.items():
        semi_x = run["geometry"]["semi_x"]
        for surface, model in itertools.product(rung["surfaces"], MODELS):
            chosen = [c["filter"] for c in run["cases"] if c["case"]["surface"] == surface
                      and c["case"]["h0_d0"] == smallest]
            if not chosen:
                continue
            qa = [2e3 * math.pi * semi_x / band_centres(f["bands"]) for f in chosen]
            diff = [np.array(f[model]) - np.array(f["3d"]) for f in chosen]
            cells = []
            for _, low, high in FILTER_RANGES:
                found = np.concatenate([d[(q >= low) & (q < high)] for q, d in zip(qa, diff)])
                found = found[np.isfinite(found)]
                cells.append("-" if not found.size else f"{found.mean():+.1f} ({found.min():+.1f} to "
                             f"{found.max():+.1f}; {int(np.sum(np.abs(found) <= ALLOWANCE_DB))}/{found.size})")
            rows.append((f"({surface})", name, model, *cells))
    return markdown_table(("surface", "indenter", "model", *(f"{label} (dB)" for label, _, _ in FILTER_RANGES)),
                          rows)


def mdr_vs_3d(runner, *, surfaces, indenters, hursts, ratios, qmin_as, realizations, cells, positions,
              wheel_radius=0.46, crown_radius=0.3, load=50e3, anisotropy=3.0, tol=1e-8) -> StudyOutcome:
    """The study (module docstring) at a rung's sizes; ``runner`` gives the seed, device and
    progress. Lengths in m, load in N; ``ratios`` the h0/d0, ``qmin_as`` the q_min a_x."""
    rung = {"surfaces": tuple(surfaces), "hursts": tuple(hursts), "ratios": tuple(ratios),
            "qmin_as": tuple(qmin_as), "realizations": realizations, "cells": cells, "positions": positions,
            "wheel_radius": wheel_radius, "crown_radius": crown_radius, "load": load, "anisotropy": anisotropy,
            "tol": tol}
    runs = {name: _run_indenter(name, rung, runner.seed, runner.device, runner.progress) for name in indenters}
    for name, run in runs.items():  # each indenter's batch, in the ensembles' record of the studies
        runner.record.append({"spec": {"seed": runner.seed, "realizations": realizations, "cases": len(run["cases"]),
                                       "algorithm": "bem + sweep", "mode": "decoupled", "boundary": "open",
                                       "indenter": name, "grid": run["grid"]},
                              "device": runner.device, "steps": positions, "seconds_each": run["seconds"]})
    forms = closed_forms(runs, rung)
    for name, run in runs.items():
        run["closed"] = forms[name]
    claims = claims_of(runs, rung)
    measurements = {"runs": runs, "closed_forms": forms, "rung": rung, "verdict_table": verdict_table(runs, rung),
                    "filter_table": filter_table(runs, rung)}
    agreeing = sum(abs(c.measured) <= ALLOWANCE_DB for c in claims)
    summary = (f"{agreeing} of {len(claims)} (surface, indenter, model, band) means lie within "
               f"{ALLOWANCE_DB:g} dB of the 3-D reference at h0/d0 = {min(ratios):g}; every case's ratio, interval "
               "and contact filter is in the measurements (docs/mdr-vs-3d.md reads them).")
    resolution = (f"{realizations} realizations of {positions} positions per case; 95 % intervals from the "
                  "realizations' scatter")
    return StudyOutcome(claims, measurements, figures(runs, forms, rung), resolution, summary)
