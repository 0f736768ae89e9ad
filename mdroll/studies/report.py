"""A study's outputs: ``<out>/<study>/<study>.json``, its PNGs and the printed table; and the page
``docs/studies.md`` assembled from a folder of such outputs (``mdroll study report DIR``), so its
numbers come from the JSONs."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

from ..experiments import markdown_table, read_record, text_table, write_figures, write_json
from ..experiments.record import INTEGER, NUMBER, OPTIONAL_NUMBER, OPTIONAL_TEXT, TABLE, TEXT, OrAbsent, \
    RecordKind, Rows, Table
from ..files import atomic_write
from . import STUDIES
from .core import AGREES, DISAGREES, REPORTED, UNRESOLVED

#: The fields of a study record (``<study>/<study>.json``) that the table and the page read.
STUDY_RECORD = RecordKind("study record", "mdroll study", {
    "study": TEXT, "title": TEXT, "thesis_figures": TEXT, "equations": TEXT, "size": TEXT, "device": TEXT,
    "resolution": TEXT, "elapsed_s": NUMBER, "environment": TABLE,
    "verdicts": Table({verdict: INTEGER for verdict in (AGREES, DISAGREES, UNRESOLVED, REPORTED)}),
    "claims": Rows({"name": TEXT, "thesis": TEXT, "unit": TEXT, "source": TEXT, "verdict": TEXT, "note": TEXT,
                    "measured": OPTIONAL_NUMBER, "expected": OPTIONAL_NUMBER, "stderr": NUMBER,
                    "allowance": OPTIONAL_NUMBER, "known": OrAbsent(OPTIONAL_TEXT)}),
    "figures": Rows({"file": TEXT, "caption": TEXT}),
    "ensembles": Rows({"spec": Table({"realizations": INTEGER, "algorithm": TEXT, "mode": TEXT, "boundary": TEXT})})})


def _number(value, unit: str = "") -> str:
    if value is None:
        return "-"
    text = f"{value:.4g}"
    return f"{text} {unit}".strip() if unit not in ("", "-") else text


def table_rows(record: dict) -> list[tuple[str, str, str, str, str]]:
    """(claim, thesis or closed form, measured, uncertainty, verdict) per claim of a study's record."""
    rows = []
    for c in record["claims"]:
        expected = "-" if c["expected"] is None else f"{_number(c['expected'], c['unit'])} ({c['source']})"
        verdict = c["verdict"] + (" (known)" if c["known"] and c["verdict"] == DISAGREES else "")
        rows.append((f"{c['name']}: {c['thesis']}", expected, _number(c["measured"], c["unit"]),
                     f"\u00b1{c['stderr']:.2g}" + (f" (allowance {c['allowance']:.2g})" if c["allowance"] else ""), verdict))
    return rows


def format_table(record: dict) -> str:
    """The study's table: thesis claim | expected | measured | uncertainty | verdict."""
    head = ("thesis claim", "expected", "measured", "uncertainty (1 sigma)", "verdict")
    rows = []
    for row in table_rows(record):
        claim = textwrap.wrap(row[0], CLAIM_WIDTH) or [""]
        rows.append((claim[0],) + row[1:])
        rows += [(more, "", "", "", "") for more in claim[1:]]
    out = [f"{record['study']} ({record['thesis_figures']}; {record['equations']}), {record['size']} size, "
           f"{record['elapsed_s']:.1f} s on {record['device']}", text_table(head, rows)]
    out += textwrap.wrap(f"resolution: {record['resolution']}", TEXT_WIDTH, subsequent_indent="  ")
    if record.get("summary"):
        out += textwrap.wrap(f"findings: {record['summary']}", TEXT_WIDTH, subsequent_indent="  ")
    return "\n".join(out)


#: Characters of the claim column of the printed table (longer claims wrap, word by word).
CLAIM_WIDTH = 48
#: Characters of a line of the printed resolution and findings.
TEXT_WIDTH = 100


def write_study(run, out) -> list[Path]:
    """Write ``<out>/<study>/<study>.json`` and its PNGs (each atomically); returns the paths."""
    folder = Path(out) / run.record["study"]
    folder.mkdir(parents=True, exist_ok=True)
    paths = write_figures(run.figures, folder)
    return [write_json(folder / f"{run.record['study']}.json", run.record)] + paths


def load_records(folder) -> list[dict]:
    """The study records under ``folder`` (``<study>/<study>.json``), in the registry's order."""
    folder = Path(folder)
    records = []
    for name in STUDIES:
        path = folder / name / f"{name}.json"
        if path.is_file():
            records.append(read_record(path, STUDY_RECORD))
    return records


def _md(text: str) -> str:
    """Plain text safe in Markdown (MyST): no emphasis from E* or q_min, no raw HTML from <J^2>,
    no table break from |."""
    for char in "\\*_|[]`":
        text = text.replace(char, "\\" + char)
    return text.replace("<", "&lt;").replace(">", "&gt;")


def page(records: list[dict], folder: Path, page_path: Path) -> str:
    """Markdown: one section per study with the thesis's figure and claim, our figure(s) and the
    table of claims, verdicts and notes, from the records alone."""
    sizes = sorted({r["size"] for r in records})
    devices = sorted({r["environment"].get("device_name", r["device"]) for r in records})
    commits = sorted({str(r.get("git_commit")) for r in records})
    versions = sorted({", ".join(f"{k} {r['environment'][k]}" for k in ("mdroll", "warp", "cupy", "numpy", "python")
                                 if r["environment"].get(k)) for r in records})
    days = sorted({r["environment"].get("date", "?")[:10] for r in records})
    lines = ["# The thesis's parameter studies", "",
             f"Generated by `mdroll study report {folder}` from the JSON records in `{folder}/` "
             "(do not edit by hand). "
             f"Size: **{', '.join(sizes)}**; device: {', '.join(devices)}; {'; '.join(versions)}; "
             f"run on {', '.join(days)}; commit: {', '.join(commits)}; "
             f"{sum(r['elapsed_s'] for r in records):.0f} s of study time in all.", ""]
    if "full" not in sizes:
        lines += ["> **These are QUICK results** (small ensembles on a CPU): many claims are *not resolved at this "
                  "size*; the full run (`mdroll study all --full --device cuda`) uses the thesis's ensembles.", ""]
    lines += ["Verdicts: *agrees* (within the allowance + 3 standard errors, and resolved), *disagrees* "
              "(outside it; *known* when the project explains it), *not resolved at this size* (3 standard errors "
              "exceed the smallest discrepancy that matters), *reported* (a measurement with no number to test).", ""]
    lines += markdown_table(("study", "thesis", "agrees", "disagrees", "not resolved", "reported"),
                            [(r["study"], r["thesis_figures"], *(r["verdicts"][v] for v in (AGREES, DISAGREES, UNRESOLVED,
                                                                                          REPORTED))) for r in records])
    for r in records:
        title = r["title"][:1].upper() + r["title"][1:]
        lines += ["", f"## {r['study']}", "", f"**Thesis {r['thesis_figures']} ({r['equations']}).** {_md(title)}.", ""]
        if r.get("summary"):
            lines += [f"**Findings.** {_md(r['summary'])}", ""]
        for fig in r["figures"]:
            image = (Path(folder) / r["study"] / fig["file"])
            try:
                image = image.relative_to(page_path.parent)
            except ValueError:
                pass
            lines += [f"![{fig['caption']}]({image.as_posix()})", "", f"*{fig['caption']}.*", ""]
        lines += markdown_table(("claim", "expected", "measured", "uncertainty (1 sigma)", "verdict"),
                                [[_md(c) for c in row] for row in table_rows(r)])
        notes = [f"- **{_md(c['name'])}**: {_md(c['note'])}" + (f" *Known disagreement:* {_md(c['known'])}" if c["known"] else "")
                 for c in r["claims"] if c["note"] or c["known"]]
        if notes:
            lines += ["", *notes]
        ensembles = r["ensembles"]
        reals = sorted({e["spec"]["realizations"] for e in ensembles})
        lines += ["", f"{len(ensembles)} ensembles ({', '.join(map(str, reals))} realizations; "
                      f"{', '.join(sorted({e['spec']['algorithm'] + ' ' + e['spec']['mode'] + ' ' + e['spec']['boundary'] for e in ensembles}))}), "
                      f"{r['elapsed_s']:.1f} s on {r['device']}. Resolution: {_md(r['resolution'])}."]
    return "\n".join(lines) + "\n"


def write_page(folder, page_path=None) -> Path:
    """Assemble the studies page from the records under ``folder`` (default page: ``<folder>.md``)."""
    folder = Path(folder)
    page_path = Path(page_path) if page_path is not None else folder.with_suffix(".md")
    records = load_records(folder)
    if not records:
        raise FileNotFoundError(f"no study records (<study>/<study>.json) under {folder}")
    with atomic_write(page_path, "w") as file:
        file.write(page(records, folder, page_path))
    return page_path
