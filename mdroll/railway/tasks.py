"""The work behind ``mdroll roughness check | filter | profile``: run, write files, print a table.

Files are written atomically (temporary file in the same folder, then rename).
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

from ..experiments import Figure, write_figure, write_json
from ..files import atomic_write
from ..roughness import bands, filters, measured
from . import track_study
from .studies import run_all


def _write_text(path: Path, text: str) -> None:
    with atomic_write(path, "w") as file:
        file.write(text)


def _passes(record: dict) -> list[tuple[str, bool]]:
    out = [(f"line spectrum {r['model']}", r["passed"]) for r in record.get("lines", [])]
    out += [(name, record[key]["passed"]) for key, name in (("round_trip", "dB round trip"),
                                                             ("measured_profile", "measured profile")) if key in record]
    out += [(f"eq 39 high band {r['model']}", r["passed"]) for r in record.get("high_band", [])]
    if "track" in record:
        out.append(("small roughness on a track = linear chain (same realizations)", record["track"]["passed"]))
    return out


def check(size: str, seed: int, device: str, out: Path, only=None) -> bool:
    """``mdroll roughness check``: :func:`mdroll.railway.studies.run_all` (``only``: some of its
    studies) into roughness.json and contact_filter.png; a summary on stdout; True when every
    check with a criterion passed."""
    record = run_all(size, seed, device, only)
    write_json(out / "roughness.json", record)
    written = ["roughness.json"]
    if "contact_filter" in record:
        write_figure(contact_filter_figure(record["contact_filter"]["cnossos"], record["contact_filter"]),
                     out / "contact_filter.png")
        written.append("contact_filter.png")
    if "track" in record:
        for figure in track_study.figures(record["track"]):
            write_figure(figure, out / f"{figure.name}.png")
            written.append(f"{figure.name}.png")
    results = _passes(record)
    print("  result  check (roughness model)")
    for name, passed in results:
        print(f"  {'PASS' if passed else 'FAIL':<6}  {name}")
    if "eq63" in record:
        e = record["eq63"]
        print(f"  {'REPORT':<6}  eq 63 (model rolloff): measured {e['rolloff']['measured_ratio']:.3g} "
              f"(\u00b1{e['rolloff']['measured_ratio_rel_stderr'] * 100:.0f} %), closed form on the band "
              f"{e['rolloff']['closed_form_band']:.3g}, eq 63 (thesis) {e['rolloff']['eq63_thesis']:.3g}")
        print(f"  {'REPORT':<6}  eq 63 (model iso3095): measured {e['iso3095']['measured_ratio']:.3g}, "
              f"closed form {e['iso3095']['closed_form_band']:.3g}")
    for case in record.get("dynamics", {}).get("cases", []):
        print(f"  {'PASS' if case['decoupled_valid'] else 'FAIL':<6}  decoupled valid (model iso3095 "
              f"{case['offset_dB']:+g} dB, v0 {case['v0']:g} m/s): contact lost {case['contact_lost_fraction']:.3g}, "
              f"max |L_a coupled - decoupled| {case['max_abs_difference_dB']:.2f} dB at {case['at_Hz']:g} Hz")
    for case in record.get("track", {}).get("cases", []):
        worst = max(abs(d) for d in case["force"]["difference_dB"])
        print(f"  {'REPORT':<6}  track {case['track']}, ISO 3095 {case['offset_dB']:+g} dB: contact lost "
              f"{case['contact_lost_fraction']:.3g}, max |L_F - linear chain| {worst:.2f} dB, dips "
              + " ".join(f"{d['over_linear_dB']:+.1f}" for d in case["dips"]) + " dB over the chain")
    print(f"wrote {out}/: {' '.join(written)}")
    return all(passed for _, passed in results)


def contact_filter_table(comparison: dict) -> str:
    """CSV: wavelength (mm), then per CNOSSOS case A3, MDR and MDR - A3 (dB)."""
    text = io.StringIO()
    writer = csv.writer(text)
    header = ["wavelength_mm"]
    for c in comparison["cases"]:
        tag = f"{c['load_N'] / 1e3:g}kN_{c['diameter_m'] * 1e3:g}mm"
        header += [f"A3_{tag}", f"MDR_{tag}", f"MDR_minus_A3_{tag}"]
    writer.writerow(header)
    for i, lam in enumerate(comparison["wavelength_mm"]):
        row = [lam]
        for c in comparison["cases"]:
            row += [c["A3_dB"][i], round(c["MDR_dB"][i], 2), round(c["difference_dB"][i], 2)]
        writer.writerow(row)
    return text.getvalue()


def contact_filter_figure(comparison: dict, measured_record: dict | None = None) -> Figure:
    """The MDR contact filter (closed band form) and CNOSSOS-EU A3 for the five cases against
    wavelength; with ``measured_record`` (:func:`studies.contact_filter_study`) the ensemble's."""
    def draw(fig):
        ax = fig.subplots()
        lam = np.array(comparison["wavelength_mm"])
        for i, c in enumerate(comparison["cases"]):
            color = f"C{i}"
            tag = f"{c['load_N'] / 1e3:g} kN, D {c['diameter_m'] * 1e3:g} mm (a = {c['a_m'] * 1e3:.2f} mm)"
            ax.semilogx(lam, c["A3_dB"], "o--", color=color, ms=3, label=f"A3 {tag}")
            ax.semilogx(lam, c["MDR_dB"], "-", color=color, label=f"MDR {tag}")
        if measured_record is not None:
            ax.semilogx(measured_record["wavelength_mm"], measured_record["measured_dB"], "k*", ms=7,
                        label=f"MDR measured (ISO 3095 ensemble, a = {measured_record['a_m'] * 1e3:.2f} mm)")
        ax.invert_xaxis()
        ax.set_xlabel("wavelength (mm)")
        ax.set_ylabel("contact filter (dB)")
        ax.set_ylim(-40, 2)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, ncol=2)

    return Figure("contact_filter", "The MDR contact filter beside CNOSSOS-EU A3", draw, size=(9, 5.5), dpi=110)


def contact_filter(out: Path) -> None:
    """``mdroll roughness filter``: contact_filter.csv, contact_filter.json and contact_filter.png."""
    comparison = filters.cnossos_comparison()
    _write_text(out / "contact_filter.csv", contact_filter_table(comparison))
    write_json(out / "contact_filter.json", comparison)
    write_figure(contact_filter_figure(comparison), out / "contact_filter.png")
    print(contact_filter_text(comparison))
    print(f"wrote {out}/: contact_filter.csv (every column) contact_filter.json contact_filter.png")


def contact_filter_text(comparison: dict) -> str:
    """The contact filter for a terminal: per wavelength and CNOSSOS case, A3 and MDR (dB)."""
    cases = comparison["cases"]
    lines = [f"case {i + 1}: {c['load_N'] / 1e3:g} kN, wheel diameter {c['diameter_m'] * 1e3:g} mm, "
             f"a = {c['a_m'] * 1e3:.2f} mm" for i, c in enumerate(cases)]
    lines.append("contact filter (dB): A3 (CNOSSOS-EU) / MDR per case")
    lines.append(f"{'lambda (mm)':>11}" + "".join(f"{f'case {i + 1}':>15}" for i in range(len(cases))))
    for i, lam in enumerate(comparison["wavelength_mm"]):
        lines.append(f"{lam:>11g}" + "".join(f"{round(c['A3_dB'][i], 1) + 0.0:>7.1f} /{round(c['MDR_dB'][i], 1) + 0.0:>6.1f}"
                                         for c in cases))
    return "\n".join(lines)


def profile(file: str, dx: float | None, segment: float | None, output) -> None:
    """``mdroll roughness profile``: profile_psd.csv (q rad/m, C m^3 two-sided, 95 % lower and
    upper; a roughness_table for roughness = "table") and profile_bands.csv (L_r per band), in
    the folder ``output()`` returns, called once the profile is read and its PSD estimated."""
    prof = measured.load_profile(file, dx)
    estimate = measured.welch_psd(prof, segment)
    out = output()
    rows = ["# Welch PSD of " + str(file) + f": Hann window, {estimate.segments} segments, dof {estimate.dof:.1f}",
            "q_rad_per_m,C_m3,lower_95,upper_95"]
    rows += [f"{q:.10g},{c:.10g},{lo:.10g},{hi:.10g}" for q, c, lo, hi in
             zip(estimate.q, estimate.psd, estimate.lower, estimate.upper) if c > 0]
    _write_text(out / "profile_psd.csv", "\n".join(rows) + "\n")
    dq = float(estimate.q[1] - estimate.q[0])
    n = bands.wavelength_bands_of_grid(dq, float(estimate.q[-1]))
    levels, counts = bands.roughness_levels(estimate.q, estimate.psd, dq, n)
    lines = ["wavelength_mm,L_r_dB_re_1um,bins"] + [f"{w:g},{l:.2f},{c}" for w, l, c in
                                                    zip(bands.nominal(n), levels, counts) if math.isfinite(l)]
    _write_text(out / "profile_bands.csv", "\n".join(lines) + "\n")
    print(f"profile {file}: {prof.h.size} points, dx {prof.dx:.4g} m, RMS {np.std(prof.h):.4g} m; "
          f"Welch {estimate.segments} segments, {estimate.dof:.1f} degrees of freedom")
    print("\n".join(lines))
    print(f"wrote {out}/: profile_psd.csv profile_bands.csv")
