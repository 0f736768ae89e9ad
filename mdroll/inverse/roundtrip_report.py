"""The round-trip study's record as Markdown tables (docs/inverse.md's sections) and a figure;
several records of a study's parts merged into one; :data:`ROUNDTRIP_RECORD`, the fields they read."""

from __future__ import annotations

import numpy as np

from ..experiments import Figure, markdown_table, write_figure
from ..experiments.record import FLAGS, INTEGER, NUMBER, NUMBERS, TEXT, OrAbsent, RecordKind, Rows
from ..errors import ParameterError
from .roundtrip import TARGETS, format_error, summarize

#: What every row of a record holds.
_ROW = {"passes": INTEGER, "L": NUMBER, "error": NUMBERS, "covered": FLAGS}
#: The fields of a round-trip record (``roundtrip.json``) that the tables and the merge read
#: (``mdroll invert --report`` reads records through :func:`mdroll.experiments.read_record`).
ROUNDTRIP_RECORD = RecordKind("round-trip record", "mdroll invert --round-trip", {
    "size": TEXT, "rows": Rows(_ROW), "seconds": NUMBER,
    "realistic": OrAbsent(Rows({**_ROW, "v0": NUMBER, "seed": INTEGER}))})


def format_table(record: dict) -> str:
    """The summary as a Markdown table: median |error| (coverage of the 95 % intervals)."""
    names = list(TARGETS)
    rows = []
    for e in record["summary"]:
        cells = []
        for n in names:
            if n not in e:
                cells.append("-")
                continue
            m = e[n]["median_abs_error"]
            value = f"{m:.4f}" if n == "H" else f"{100 * m:.2f}"
            cells.append(f"{value} ({100 * e[n]['coverage']:.0f}%)")
        rows.append((e["passes"], f"{e['L']:g}", e["round_trips"], *cells))
    for row in record.get("realistic", []):
        cells = [_realistic_cell(row, n) if n in row["error"] else "-" for n in names]
        rows.append((row["passes"], f"{row['L']:g}", f"realistic v0={row['v0']:g} seed {row['seed']}", *cells))
    head = ("K", "L (m)", "trips", *(f"{n} ({'abs' if n == 'H' else '%'})" for n in names))
    return "\n".join(markdown_table(head, rows))


def _realistic_cell(row: dict, name: str) -> str:
    """A realistic case's error and coverage; the widening of its interval over the statistical one
    by the model discrepancy and the fill check together (where 10 % or more), and the statistical
    interval's verdict where it differs (the one before the fill check in records without the
    discrepancy)."""
    text = format_error(name, row["error"][name]) + (" in" if row["covered"][name] else " out")
    widening, statistical = 1.0, row["covered"][name]
    for part, verdict in (("fill_check", "covered_local"), ("discrepancy", "covered_without")):
        extra = row.get(part)
        if extra:
            widening *= extra["widening"][name]
            statistical = extra[verdict][name]  # the discrepancy's is before the fill check too
    if widening >= 1.1:
        text += f" x{widening:.1f}"
    if statistical != row["covered"][name]:
        text += " (statistical: " + ("in" if statistical else "out") + ")"
    return text


def merge_records(records) -> dict:
    """One record from the records of several parts of a study (their rows and realistic cases, a
    later realistic case replacing an earlier one of the same K, L, v0 and seed; the summary recomputed,
    the seconds summed)."""
    records = list(records)
    if not records:
        raise ParameterError("no round-trip record to report on")
    rows = [row for r in records for row in r["rows"]]
    realistic = {}  # a later record's realistic case replaces an earlier one's at the same K, L, v0 and seed
    for row in (row for r in records for row in r.get("realistic", [])):
        realistic[(row["passes"], row["L"], row["v0"], row["seed"])] = row
    return {"size": records[0]["size"], "rows": rows, "summary": summarize(rows),
            "realistic": list(realistic.values()), "targets": TARGETS,
            "correction": records[0].get("correction", "none"), "seconds": sum(r["seconds"] for r in records)}


def report(record: dict) -> str:
    """The Markdown of docs/inverse.md's round-trip sections from a (merged) record: the table of
    :func:`format_table`; where the rows carry the closed form's errors, its median |error| and
    median signed H error beside the corrected ones; per true parameter set at the largest (K, L)
    the median signed errors and coverage; and the fits that did not converge or were not
    corrected."""
    rows = record["rows"]
    out = [format_table(record), ""]
    if not rows:  # the realistic cases alone
        return out[0]
    corrected = [r for r in rows if "error_closed_form" in r]
    if corrected:
        table = []
        for key in sorted({(r["passes"], r["L"]) for r in corrected}):
            cell = [r for r in corrected if (r["passes"], r["L"]) == key]

            def median(name, field, signed=False):
                values = [r[field][name] for r in cell if name in r[field]]
                return float(np.median(values if signed else np.abs(values)))

            table.append((key[0], f"{key[1]:g}", f"{median('H', 'error_closed_form'):.4f}", f"{median('H', 'error'):.4f}",
                          f"{median('H', 'error_closed_form', True):+.4f}", f"{median('H', 'error', True):+.4f}",
                          *(f"{100 * median(n, field):.2f}" for n in ("h0", "E_star")
                            for field in ("error_closed_form", "error"))))
        out += ["Closed form (the first iterate) against the corrected fit: median |error|, and the median signed "
                "error of H:", "", *markdown_table(("K", "L (m)", "H closed", "H corrected", "H signed closed",
                                                    "H signed corrected", "h0 closed (%)", "h0 corrected (%)",
                                                    "E_star closed (%)", "E_star corrected (%)"), table), ""]
    largest = max((r["passes"], r["L"]) for r in rows)
    cell = [r for r in rows if (r["passes"], r["L"]) == largest]
    table = []
    for change in sorted({json_key(r["change"]) for r in cell}):
        group = [r for r in cell if json_key(r["change"]) == change]
        cells = []
        for n in TARGETS:
            errors = [r["error"][n] for r in group if n in r["error"]]
            cover = np.mean([r["covered"][n] for r in group if n in r["covered"]])
            cells.append(f"{format_error(n, float(np.median(errors)))} ({100 * cover:.0f}%)")
        table.append((change, len(group), *cells))
    out += [f"Per true parameter set at K = {largest[0]}, L = {largest[1]:g} m: median signed error (coverage):", "",
            *markdown_table(("truth", "trips", *TARGETS), table)]
    failed = [r for r in rows if not r["success"]]
    messages = sorted({r.get("message", "") for r in failed})
    skipped = [r for r in rows if r.get("correction_skipped")]
    unconverged = [r for r in corrected if not r.get("converged") and not r.get("correction_skipped")]
    out += ["", f"{len(rows)} round trips; optimizer success false in {len(failed)} ({'; '.join(messages) or '-'}); "
            f"correction skipped in {len(skipped)}, not converged in {len(unconverged)}; "
            f"{record['seconds']:.0f} s in all."]
    return "\n".join(out)


def json_key(change: dict) -> str:
    """A true parameter set's change from the defaults, as text (``defaults`` for none)."""
    return ", ".join(f"{k}={v:.6g}" for k, v in sorted(change.items())) or "defaults"


def study_figure(record: dict) -> Figure:
    """|error| against K for each L and parameter (median over the truths), with the targets."""
    names = list(TARGETS)

    def draw(fig):
        axes = fig.subplots(1, len(names))
        for ax, name in zip(axes, names):
            for length in sorted({e["L"] for e in record["summary"]}):
                cells = [e for e in record["summary"] if e["L"] == length and name in e]
                scale = 1.0 if name == "H" else 100.0
                ax.loglog([e["passes"] for e in cells],
                          [max(scale * e[name]["median_abs_error"], 1e-6) for e in cells], "o-", label=f"L = {length:g} m")
            ax.axhline(TARGETS[name] * (1.0 if name == "H" else 100.0), color="0.5", ls="--", lw=0.8)
            ax.set_title(f"{name}: median |error|" + ("" if name == "H" else " (%)"), fontsize=9)
            ax.set_xlabel("passes K")
        axes[0].legend(fontsize=8)

    return Figure("roundtrip", "Median |error| of the round trips against the passes K, per L, with the targets", draw,
                  size=(3.2 * len(names), 3.2), dpi=120)


def plot_study(record: dict, path) -> None:
    """Write :func:`study_figure` as PNG to ``path`` (a path or a binary file)."""
    write_figure(study_figure(record), path)
