"""The one table writer of the experiments: aligned text for the terminal, Markdown for the docs."""

from __future__ import annotations


def text_table(head, rows, align: str = "", rule: bool = True) -> str:
    """Columns padded to their widest cell, two spaces apart; ``align`` one character per column,
    ``l`` or ``r`` (default left); a rule of dashes under the head."""
    rows = [tuple(str(c) for c in row) for row in rows]
    head = tuple(str(c) for c in head)
    widths = [max(len(row[i]) for row in [head, *rows]) for i in range(len(head))]
    align = align.ljust(len(head), "l")

    def line(row):
        return "  ".join(cell.rjust(w) if a == "r" else cell.ljust(w)
                         for cell, w, a in zip(row, widths, align)).rstrip()

    out = [line(head)] + (["-" * (sum(widths) + 2 * (len(widths) - 1))] if rule else [])
    return "\n".join(out + [line(row) for row in rows])


def markdown_table(head, rows) -> list[str]:
    """A Markdown table (lines): the head, its rule, one line per row."""
    return (["| " + " | ".join(map(str, head)) + " |", "|" + "---|" * len(head)]
            + ["| " + " | ".join(map(str, row)) + " |" for row in rows])
