"""The validation table, ``validation.json``, one PNG per check and JUnit XML, each written atomically."""

from __future__ import annotations

import json
import math
import re
import xml.etree.ElementTree as ET
from pathlib import Path

from ..files import atomic_write
from .api import CheckResult


def format_table(results: list[CheckResult]) -> str:
    """One row per check: name, equation, measured, predicted, ratio, tolerance, PASS/FAIL."""
    header = f"{'check':<22} {'eq':<18} {'measured':>12} {'predicted':>12} {'ratio':>8} {'tolerance':>10}  result"
    rows = [header, "-" * len(header)]
    for r in results:
        rows.append(f"{r.name:<22} {r.equation:<18} {r.measured:>12.5g} {r.predicted:>12.5g} {_ratio_text(r):>8} "
                    f"{r.tolerance_text():>10}  {'PASS' if r.passed else 'FAIL'}")
    passed = sum(r.passed for r in results)
    rows.append(f"{passed}/{len(results)} passed")
    return "\n".join(rows)


def _ratio_text(r: CheckResult) -> str:
    return f"{r.ratio:.4f}" if math.isfinite(r.ratio) else "-"


def slug(name: str) -> str:
    """A file-name form of a check name: ``eq 23 slope H=0.5`` -> ``eq_23_slope_H0.5``."""
    return re.sub(r"[^A-Za-z0-9.]+", "_", name.replace("=", "")).strip("_")


def message(r: CheckResult) -> str:
    """One line: measured vs predicted, the ratio and the tolerance."""
    label = f"{r.name} ({r.equation})" if r.equation else r.name
    unit = "" if r.unit == "-" else f" {r.unit}"
    return (f"{label}: measured {r.measured:.6g}{unit}, predicted {r.predicted:.6g}{unit}, ratio {_ratio_text(r)}, "
            f"tolerance {r.tolerance_text()}: {'PASS' if r.passed else 'FAIL'}; {r.note}")


def junit_xml(results: list[CheckResult], suite: str = "mdroll.validate", seconds: float = 0.0) -> bytes:
    """A JUnit XML document: one ``<testcase>`` per check (classname = equation), its measured,
    predicted, ratio, tolerance, kind and unit as ``<property>`` elements, a ``<failure>`` with
    :func:`message` when it failed and the message as ``<system-out>`` either way."""
    failures = sum(not r.passed for r in results)
    root = ET.Element("testsuites", tests=str(len(results)), failures=str(failures), errors="0")
    node = ET.SubElement(root, "testsuite", name=suite, tests=str(len(results)), failures=str(failures), errors="0",
                         skipped="0", time=f"{seconds:.3f}")
    for r in results:
        case = ET.SubElement(node, "testcase", classname=f"{suite}.{slug(r.equation) or 'check'}", name=r.name, time="0")
        props = ET.SubElement(case, "properties")
        for key in ("measured", "predicted", "ratio", "tolerance", "kind", "unit"):
            value = getattr(r, key)
            if key == "ratio" and not math.isfinite(value):
                continue  # a prediction of 0 has no ratio
            ET.SubElement(props, "property", name=key, value=repr(float(value)) if isinstance(value, float) else str(value))
        if not r.passed:
            ET.SubElement(case, "failure", message=message(r), type="CheckFailed").text = message(r)
        ET.SubElement(case, "system-out").text = message(r)
    return ET.tostring(root, encoding="utf-8", xml_declaration=True)


def write_junit(results: list[CheckResult], path, **kwargs) -> Path:
    """Write :func:`junit_xml` to ``path`` atomically."""
    path = Path(path)
    with atomic_write(path) as file:
        file.write(junit_xml(results, **kwargs))
    return path


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
    with atomic_write(paths[0], "w") as file:
        json.dump(record, file, indent=2, default=float)
    for r in results:
        if r.plot is None:
            continue
        fig, ax = plt.subplots(figsize=(6, 4), layout="constrained")
        r.plot(ax)
        measured = (f"ratio {r.ratio:.4f}" if math.isfinite(r.ratio)
                    else f"measured {r.measured:.4g}, predicted {r.predicted:.4g}")
        ax.set_title(f"{r.name} ({r.equation}): {measured}, {'PASS' if r.passed else 'FAIL'}", fontsize=9)
        path = out / f"{slug(r.name)}.png"
        with atomic_write(path) as file:
            fig.savefig(file, dpi=110, format="png")
        plt.close(fig)
        paths.append(path)
    return paths
