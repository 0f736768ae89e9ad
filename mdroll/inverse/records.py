"""The reader of round-trip records (``roundtrip.json``): every field the report reads checked,
naming the file and the field, so that a record of another schema, a truncated file or an edited
one ends in one line instead of deep inside the report."""

from __future__ import annotations

import json
import math
from pathlib import Path

from ..errors import ParameterError

#: What every row of a record holds, and the checks of its values.
_ROW_FIELDS = {"passes": "an integer", "L": "a number", "error": "a table of numbers", "covered": "a table of true/false"}
#: What a realistic case holds beside a row's fields.
_REALISTIC_FIELDS = {"v0": "a number", "seed": "an integer"}


def _valid(value, kind: str) -> bool:
    number = isinstance(value, (int, float)) and not isinstance(value, bool)
    if kind == "an integer":
        return isinstance(value, int) and not isinstance(value, bool)
    if kind == "a number":
        return number and math.isfinite(value)
    if kind == "a table of numbers":
        return isinstance(value, dict) and all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                               for v in value.values())
    return isinstance(value, dict) and all(isinstance(v, bool) for v in value.values())


def _check_rows(path, rows, where: str, fields: dict) -> None:
    if not isinstance(rows, list):
        raise ParameterError(f"{path}: {where} must be a list of rows, got {type(rows).__name__}")
    for i, row in enumerate(rows):
        if not isinstance(row, dict):
            raise ParameterError(f"{path}: {where}[{i}] must be a table, got {type(row).__name__}")
        for name, kind in fields.items():
            if name not in row:
                raise ParameterError(f"{path}: {where}[{i}] lacks {name!r} ({kind})")
            if not _valid(row[name], kind):
                raise ParameterError(f"{path}: {where}[{i}].{name} = {row[name]!r}, expected {kind}")


def read_record(path) -> dict:
    """The round-trip record at ``path`` (as ``mdroll invert --round-trip`` writes it), checked."""
    file = Path(path)
    try:
        record = json.loads(file.read_text())
    except FileNotFoundError:
        raise ParameterError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise ParameterError(f"{path}: a directory; give its roundtrip.json") from None
    except (UnicodeDecodeError, json.JSONDecodeError):
        raise ParameterError(f"{path}: not a JSON round-trip record (truncated, or another format)") from None
    if not isinstance(record, dict) or not {"size", "rows", "seconds"} <= set(record):
        raise ParameterError(f"{path}: not a round-trip record (it needs the fields size, rows and seconds, as "
                             "mdroll invert --round-trip writes them)")
    if not isinstance(record["size"], str):
        raise ParameterError(f"{path}: size = {record['size']!r}, expected a text (quick or full)")
    if not _valid(record["seconds"], "a number"):
        raise ParameterError(f"{path}: seconds = {record['seconds']!r}, expected a number")
    _check_rows(path, record["rows"], "rows", _ROW_FIELDS)
    _check_rows(path, record.get("realistic", []), "realistic", {**_ROW_FIELDS, **_REALISTIC_FIELDS})
    return record
