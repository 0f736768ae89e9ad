"""The validation table, ``validation.json`` and one PNG per check."""

from __future__ import annotations

import json
import re
from pathlib import Path

from .checks import CheckResult


def format_table(results: list[CheckResult]) -> str:
    """One row per check: name, equation, measured, predicted, ratio, tolerance, PASS/FAIL."""
    header = f"{'check':<22} {'eq':<18} {'measured':>12} {'predicted':>12} {'ratio':>8} {'tolerance':>10}  result"
    rows = [header, "-" * len(header)]
    for r in results:
        rows.append(f"{r.name:<22} {r.equation:<18} {r.measured:>12.5g} {r.predicted:>12.5g} {r.ratio:>8.4f} "
                    f"{r.tolerance_text():>10}  {'PASS' if r.passed else 'FAIL'}")
    passed = sum(r.passed for r in results)
    rows.append(f"{passed}/{len(results)} passed")
    return "\n".join(rows)


def slug(name: str) -> str:
    """A file-name form of a check name: ``eq 23 slope H=0.5`` -> ``eq_23_slope_H0.5``."""
    return re.sub(r"[^A-Za-z0-9.]+", "_", name.replace("=", "")).strip("_")


def write_report(results: list[CheckResult], out, meta: dict) -> list[Path]:
    """Write ``validation.json`` (records and ``meta``: size, seed, device, versions, date) and
    one PNG per check that draws a figure, into the directory ``out``; returns the paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    record = {**meta, "passed": all(r.passed for r in results), "checks": [r.as_dict() for r in results]}
    paths = [out / "validation.json"]
    paths[0].write_text(json.dumps(record, indent=2, default=float))
    for r in results:
        if r.plot is None:
            continue
        fig, ax = plt.subplots(figsize=(6, 4), layout="constrained")
        r.plot(ax)
        ax.set_title(f"{r.name} ({r.equation}): ratio {r.ratio:.4f}, {'PASS' if r.passed else 'FAIL'}", fontsize=9)
        path = out / f"{slug(r.name)}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths
