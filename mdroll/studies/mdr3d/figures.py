"""The figures of the MDR-against-3-D study (:class:`mdroll.experiments.Figure`): the band ratios
with their 95 % intervals (the MDR variants and the DPRS bed), the contact filters measured and
closed, and the five CNOSSOS-EU cases."""

from __future__ import annotations

import numpy as np

from ...experiments import Figure
from ...roughness.bands import band_centres

COLOURS = {"a": "tab:blue", "b": "tab:orange", "c": "tab:green"}
MARKERS = {"mdr": "o", "line": "x", "corrected": "s", "dprs": "d"}
STYLES = {"3d": ("k", "-"), "line": ("tab:blue", "--"), "corrected": ("tab:green", ":"), "dprs": ("tab:purple", "-.")}


def _ratios(fig, runs):
    axes = fig.subplots(len(runs), 3, sharey=True, squeeze=False)
    for row, (name, run) in enumerate(runs.items()):
        for col, band in enumerate(("low", "high", "dips")):
            ax = axes[row, col]
            ax.axhspan(-1.0, 1.0, color="0.9")
            for i, case in enumerate(run["cases"]):
                for k, (variant, marker) in enumerate(MARKERS.items()):
                    r = (case["dprs"] if variant == "dprs" else case["variants"][variant])[band]
                    if r["dB"] is None:
                        continue
                    low, high = r["ci95_dB"]
                    ax.errorbar(i + 0.2 * (k - 1.5), r["dB"], yerr=[[r["dB"] - low], [high - r["dB"]]], fmt=marker,
                                ms=3, lw=0.6, color=COLOURS[case["case"]["surface"]])
            ax.set_title(f"{name}: {band} band", fontsize=8)
            ax.set_xlabel("case (surface, H, h0/d0, q_min a)", fontsize=7)
            ax.tick_params(labelsize=7)
        axes[row, 0].set_ylabel("model / 3-D (dB)", fontsize=8)
    handles = [axes[0, 0].plot([], [], MARKERS[v], color="0.3", label=v)[0] for v in MARKERS]
    handles += [axes[0, 0].plot([], [], "-", color=c, label=f"({s})")[0] for s, c in COLOURS.items()]
    fig.legend(handles=handles, loc="outside right center", fontsize=7)


def _filters(fig, runs, forms):
    axes = fig.subplots(len(runs), 3, sharey=True, squeeze=False)
    for row, (name, run) in enumerate(runs.items()):
        closed = forms[name]
        for col, surface in enumerate(("a", "b", "c")):
            ax = axes[row, col]
            chosen = [c for c in run["cases"] if c["case"]["surface"] == surface]
            if not chosen:
                ax.set_visible(False)
                continue
            case = min(chosen, key=lambda c: (c["case"]["h0_d0"], c["case"]["qmin_a"]))
            lam = band_centres(case["filter"]["bands"])
            ax.semilogx(lam, case["filter"]["3d"], "ko", ms=4, label="3-D (BEM)")
            for variant, marker in MARKERS.items():
                label, colour = ("DPRS", "tab:purple") if variant == "dprs" else (f"MDR {variant}", None)
                ax.semilogx(lam, case["filter"][variant], marker, ms=3, color=colour, label=label)
            lam_c = band_centres(closed["bands"])
            for model, (colour, style) in STYLES.items():
                ax.semilogx(lam_c, closed[surface][model], style, color=colour, lw=0.8, label=f"linear {model}")
            if "A3" in closed:
                values = np.array([np.nan if v is None else v for v in closed["A3"]], dtype=float)
                ax.semilogx(lam_c, values, "r^", ms=4, label="CNOSSOS-EU A3")
            ax.set_title(f"{name}, ({surface}): {case['label']}", fontsize=7)
            ax.invert_xaxis()
            ax.set_xlabel("wavelength (mm)", fontsize=7)
            ax.tick_params(labelsize=7)
        axes[row, 0].set_ylabel("contact filter (dB)", fontsize=8)
    handles, labels = axes[0, 1].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside right center", fontsize=7)


def _cnossos(fig, forms):
    data = forms["cnossos"]
    lam = np.array(data["wavelength_mm"])
    axes = fig.subplots(1, len(data["cases"]), sharey=True, squeeze=False)[0]
    for ax, case in zip(axes, data["cases"]):
        ax.semilogx(lam, case["A3_dB"], "r^-", ms=3, lw=0.8, label="A3")
        ax.semilogx(lam, case["MDR_dB"], "b--", lw=0.8, label="MDR eq 39")
        ax.semilogx(lam, case["3d_corrugation_dB"], "k-", lw=0.8, label="3-D, corrugation")
        ax.semilogx(lam, case["3d_isotropic_dB"], "k:", lw=1.0, label="3-D, isotropic")
        ax.semilogx(lam, case["dprs_corrugation_dB"], "-", color="tab:purple", lw=0.8, label="DPRS, corrugation")
        ax.semilogx(lam, case["dprs_isotropic_dB"], ":", color="tab:purple", lw=1.0, label="DPRS, isotropic")
        ax.set_xlim(100, 0.8)
        ax.set_ylim(-40, 2)
        ax.set_title(f"{case['load_N'] / 1e3:g} kN, {case['diameter_m'] * 1e3:g} mm", fontsize=8)
        ax.set_xlabel("wavelength (mm)", fontsize=7)
        ax.tick_params(labelsize=7)
    axes[0].set_ylabel("contact filter (dB)", fontsize=8)
    axes[0].legend(fontsize=6)


def figures(runs: dict, forms: dict, rung: dict) -> list:
    """The study's three figures."""
    return [
        Figure("mdr_vs_3d_bands", "MDR over 3-D force PSD per band and case, and the DPRS's over its stiffness "
               "(95 % intervals), grey: within 1 dB",
               lambda fig: _ratios(fig, runs), size=(10.0, 2.6 * len(runs))),
        Figure("mdr_vs_3d_filter", "Contact filters at the smallest h0/d0 and q_min: measured (markers), linear "
               "closed forms (lines; DPRS: distributed point-reacting springs), CNOSSOS-EU A3",
               lambda fig: _filters(fig, runs, forms), size=(11.0, 3.0 * len(runs))),
        Figure("mdr_vs_3d_cnossos", "The five CNOSSOS-EU A3 cases against the MDR's eq 39 and the linear 3-D "
               f"and DPRS filters of the wheel-by-crown ellipse (crown radius {rung['crown_radius']:g} m, "
               f"H {rung['hursts'][0]:g})",
               lambda fig: _cnossos(fig, forms), size=(12.0, 3.0)),
    ]
