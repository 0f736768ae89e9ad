"""The reader of study records (``<study>/<study>.json``): every field the page reads checked,
naming the file and the field, so that a record of another schema, a truncated file or an
edited one ends in one line (``mdroll study report``) instead of deep inside the page."""

from __future__ import annotations

import json
import math
from pathlib import Path

from ..errors import ParameterError

TEXT, NUMBER, OPTIONAL_NUMBER, INTEGER, TABLE, LIST = "a text", "a number", "a number or null", "an integer", \
    "a table", "a list"
#: The fields of a record the page reads, and what each must be.
RECORD_FIELDS = {"study": TEXT, "title": TEXT, "thesis_figures": TEXT, "equations": TEXT, "size": TEXT, "device": TEXT,
                 "resolution": TEXT, "elapsed_s": NUMBER, "environment": TABLE, "verdicts": TABLE, "claims": LIST,
                 "figures": LIST, "ensembles": LIST}
CLAIM_FIELDS = {"name": TEXT, "thesis": TEXT, "unit": TEXT, "source": TEXT, "verdict": TEXT, "note": TEXT,
                "measured": OPTIONAL_NUMBER, "expected": OPTIONAL_NUMBER, "stderr": NUMBER,
                "allowance": OPTIONAL_NUMBER}
FIGURE_FIELDS = {"file": TEXT, "caption": TEXT}
SPEC_FIELDS = {"realizations": INTEGER, "algorithm": TEXT, "mode": TEXT, "boundary": TEXT}


def _is(value, kind: str) -> bool:
    number = isinstance(value, (int, float)) and not isinstance(value, bool)
    return {TEXT: isinstance(value, str), NUMBER: number and math.isfinite(value),
            OPTIONAL_NUMBER: value is None or number, INTEGER: isinstance(value, int) and not isinstance(value, bool),
            TABLE: isinstance(value, dict), LIST: isinstance(value, list)}[kind]


def _check(path, table, fields: dict, where: str) -> None:
    if not isinstance(table, dict):
        raise ParameterError(f"{path}: {where} must be a table, got {type(table).__name__}")
    for name, kind in fields.items():
        if name not in table:
            raise ParameterError(f"{path}: {where} lacks {name!r} ({kind}): not a study record of this mdroll")
        if not _is(table[name], kind):
            raise ParameterError(f"{path}: {where}{name} = {str(table[name])[:40]!r}, expected {kind}")


def read_record(path, verdicts) -> dict:
    """The study record at ``path``, checked (``verdicts``: the verdict names its counts hold)."""
    file = Path(path)
    try:
        record = json.loads(file.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError):
        raise ParameterError(f"{path}: not a JSON study record (truncated, or another format)") from None
    _check(path, record, RECORD_FIELDS, "")
    counts = record["verdicts"]
    if any(not _is(counts.get(v), INTEGER) for v in verdicts):
        raise ParameterError(f"{path}: verdicts must count each of {', '.join(verdicts)}")
    for i, claim in enumerate(record["claims"]):
        _check(path, claim, CLAIM_FIELDS, f"claims[{i}].")
        if not (claim.get("known") is None or isinstance(claim.get("known"), str)):
            raise ParameterError(f"{path}: claims[{i}].known must be a text or null")
    for i, figure in enumerate(record["figures"]):
        _check(path, figure, FIGURE_FIELDS, f"figures[{i}].")
    for i, ensemble in enumerate(record["ensembles"]):
        _check(path, ensemble, {"spec": TABLE}, f"ensembles[{i}].")
        _check(path, ensemble["spec"], SPEC_FIELDS, f"ensembles[{i}].spec.")
    return record
