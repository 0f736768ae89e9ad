"""The scaling study's record as a table and a plot, with what the registry expects of each
algorithm (:mod:`mdroll.forces.registry`)."""

from __future__ import annotations

import numpy as np

from ..experiments import Figure, text_table, write_figure
from ..forces.registry import REGISTRY


def expected_exponent(section: str, name: str) -> float | None:
    """The exponent p of time ~ n^p that the registry expects of an algorithm, or of one of its
    bench variants, in ``section`` ("refinement" or "distance"); None where no single value fits."""
    for entry in REGISTRY.values():
        if entry.name == name:
            return entry.complexity.refinement if section == "refinement" else entry.complexity.distance
        for variant in entry.bench_variants:
            if variant.name == name:
                return variant.refinement if section == "refinement" else entry.complexity.distance
    return None


def refinement_note(name: str) -> str:
    """Why an algorithm has no expected refinement exponent (its registry entry's note)."""
    entry = REGISTRY.get(name)
    return entry.complexity.note if entry is not None else ""


def format_table(record: dict) -> str:
    """The fitted exponents, the CPU-vs-CUDA ratios and the stage breakdowns as text."""
    rows = []
    for section, per_device in record["fits"].items():
        for device, per_alg in per_device.items():
            for alg, fit in per_alg.items():
                expected = expected_exponent(section, alg)
                note = f"expected ~{expected:g}" if expected is not None else refinement_note(alg)
                rows.append((section, device, alg, f"{fit['exponent']:.3f}", f"+- {fit['stderr']:.3f}", note))
    lines = ["scaling exponents (time ~ n^p, least squares on log-log, +- standard error)",
             text_table(("section", "device", "algorithm", "p", "stderr", "expected"), rows, align="lllrrl")]
    for row in record["cpu_vs_cuda"]:
        speed = ", ".join(f"{k[8:]} {v:.0f}x" for k, v in row.items() if k.startswith("speedup_"))
        lines.append(f"  cpu vs cuda {row['algorithm']:<6} n = {row['n']}, R = {row['realizations']}: {speed}")
    for device, st in record["stages"].items():
        parts = ", ".join(f"{k} {v:.3f}" for k, v in st["timings_s"].items())
        lines.append(f"  stages {device} (L = {st['params']['L']} m, R = {st['params']['n_real']}): {parts}; total {st['total_s']:.3f} s")
    for device, mem in record["memory_bytes_per_realization"].items():
        lines.append(f"  memory {device} per realization at the defaults: "
                     + ", ".join(f"{k} {v / 2**20:.1f} MiB" for k, v in mem.items()))
    return "\n".join(lines)


def study_figure(record: dict) -> Figure:
    """Log-log time vs n with the fitted lines: one colour per algorithm, solid CUDA, dashed CPU;
    one panel per sweep (refinement, distance)."""
    sections = [s for s in ("refinement", "distance") if record[s]]
    names = [n for entry in REGISTRY.values() for n in (entry.name, *(v.name for v in entry.bench_variants))]
    colours = {name: f"C{i}" for i, name in enumerate(names)}

    def draw(fig):
        axes = fig.subplots(1, len(sections), squeeze=False)
        for ax, section in zip(axes[0], sections):
            for device in sorted({r["device"] for r in record[section]}):
                for alg in colours:
                    pts = [r for r in record[section] if r["device"] == device and r["algorithm"] == alg]
                    if not pts:
                        continue
                    n = np.array([r["n"] for r in pts], float)
                    t = np.array([r["force_s"] for r in pts])
                    style = "--" if device == "cpu" else "-"
                    ax.loglog(n, t, "o", color=colours[alg], ms=4)
                    fit = record["fits"].get(section, {}).get(device, {}).get(alg)
                    if fit:
                        c = np.mean(np.log(t) - fit["exponent"] * np.log(n))
                        ax.loglog(n, np.exp(c) * n ** fit["exponent"], style, color=colours[alg],
                                  label=f"{alg} {device}: n^{fit['exponent']:.2f}")
            ax.set_xlabel("n (points per line)")
            ax.set_ylabel("force time (s)")
            ax.set_title("refinement at fixed L" if section == "refinement" else "rolling distance at fixed dx")
            ax.legend(fontsize=7)

    return Figure("bench", "Force time against n per algorithm and device, with the fitted exponents", draw,
                  size=(6 * len(sections), 4.5), dpi=110)


def plot_study(record: dict, path) -> None:
    """Write :func:`study_figure` as PNG to ``path``."""
    write_figure(study_figure(record), path)
