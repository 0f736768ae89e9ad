"""The validation table, ``validation.json``, one PNG per check and JUnit XML, each written atomically."""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from pathlib import Path

from ..experiments import Figure, text_table, write_figures, write_json
from ..files import atomic_write
from .api import CheckResult


def format_table(results: list[CheckResult]) -> str:
    """One row per check: name, equation, measured, predicted, ratio, tolerance, PASS/FAIL."""
    head = ("check", "eq", "measured", "predicted", "ratio", "tolerance", "result")
    rows = [(r.name, r.equation, f"{r.measured:.5g}", f"{r.predicted:.5g}", _ratio_text(r), r.tolerance_text(),
             "PASS" if r.passed else "FAIL") for r in results]
    passed = sum(r.passed for r in results)
    return text_table(head, rows, align="llrrrrl") + f"\n{passed}/{len(results)} passed"


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


def figure(r: CheckResult) -> Figure:
    """The figure of a check that draws one: its plot callback on one Axes, titled with the verdict."""
    def draw(fig):
        ax = fig.subplots()
        r.plot(ax)
        ax.set_title(f"{r.name} ({r.equation}): ratio {r.ratio:.4f}, {'PASS' if r.passed else 'FAIL'}", fontsize=9)

    return Figure(slug(r.name), message(r), draw, size=(6, 4), dpi=110)


def write_report(results: list[CheckResult], out, meta: dict) -> list[Path]:
    """Write ``validation.json`` and one PNG per check that draws a figure into the directory
    ``out``; returns the paths. The record: ``meta`` (the run's
    :func:`mdroll.experiments.provenance`: size, seed, parameters, environment, commit; and the
    cache's hits), whether every check passed and each check's record."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    record = {**meta, "passed": all(r.passed for r in results), "checks": [r.as_dict() for r in results]}
    return [write_json(out / "validation.json", record, indent=2)] + write_figures(
        [figure(r) for r in results if r.plot is not None], out)
