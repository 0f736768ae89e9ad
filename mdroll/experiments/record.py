"""An experiment's record: JSON with where, when and with what it was computed.

:func:`provenance` gives the keys every record carries: ``size``, ``seed``, ``parameters`` (the
rung's, JSON-ready), ``environment`` (:func:`mdroll.provenance.environment`: device and its name,
mdroll and library versions, platform, date) and ``git_commit``. :func:`write_json` writes a
record atomically; :func:`read_record` reads one back, checked against the fields its
:class:`RecordKind` names, so that a file of another kind, a truncated or an edited one ends in
one :class:`~mdroll.errors.ParameterError` naming the file and the field instead of deep inside
the code that reads it.
"""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
from dataclasses import dataclass
from pathlib import Path

from ..devices import resolve_device
from ..errors import ParameterError
from ..files import atomic_write, jsonable
from ..provenance import environment


def git_commit() -> str | None:
    """The commit of the mdroll checkout (with ``+dirty`` for uncommitted changes), or None."""
    root = Path(__file__).resolve().parents[2]
    try:
        commit = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True,
                                timeout=10)
        if commit.returncode != 0:
            return None
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=10).stdout.strip()
        return commit.stdout.strip() + ("+dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return None


def _plain(value):
    """A rung's parameters as JSON values: dataclasses (and objects with ``as_dict``) as dicts."""
    if hasattr(value, "as_dict"):
        return value.as_dict()
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def provenance(device: str, size: str | None = None, seed: int | None = None, parameters=None,
               devices=None) -> dict:
    """The provenance keys of a record (module docstring) for a run on ``device`` ("auto" is
    resolved); ``devices``: several devices, each with its own environment (``environment`` then
    maps device -> dict)."""
    env = {d: environment(d) for d in devices} if devices is not None else environment(resolve_device(device))
    return {"size": size, "seed": seed, "parameters": jsonable(_plain(parameters)), "environment": env,
            "git_commit": git_commit()}


def write_json(path, record: dict, indent: int = 1) -> Path:
    """Write ``record`` as JSON to ``path`` atomically (NumPy values made JSON-ready)."""
    path = Path(path)
    with atomic_write(path, "w") as file:
        file.write(json.dumps(jsonable(record), indent=indent) + "\n")
    return path


# ----------------------------------------------------------------------------- reading one back
TEXT, OPTIONAL_TEXT, INTEGER, NUMBER, OPTIONAL_NUMBER = "a text", "a text or null", "an integer", "a number", \
    "a number or null"
TABLE, NUMBERS, FLAGS = "a table", "a table of numbers", "a table of true/false"


def _number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


#: What each value kind of a field admits.
_ADMITS = {TEXT: lambda v: isinstance(v, str), OPTIONAL_TEXT: lambda v: v is None or isinstance(v, str),
           INTEGER: lambda v: isinstance(v, int) and not isinstance(v, bool),
           NUMBER: lambda v: _number(v) and math.isfinite(v), OPTIONAL_NUMBER: lambda v: v is None or _number(v),
           TABLE: lambda v: isinstance(v, dict),
           NUMBERS: lambda v: isinstance(v, dict) and all(_number(x) for x in v.values()),
           FLAGS: lambda v: isinstance(v, dict) and all(isinstance(x, bool) for x in v.values())}


@dataclass(frozen=True)
class Table:
    """A field that is a table with these ``fields`` (name -> kind)."""

    fields: dict


@dataclass(frozen=True)
class Rows:
    """A field that is a list of tables, each with these ``fields``."""

    fields: dict


@dataclass(frozen=True)
class OrAbsent:
    """A field that a record may lack; where present, of ``kind``."""

    kind: object


@dataclass(frozen=True)
class RecordKind:
    """What a kind of record is called (``name``), which command writes it (``writer``) and the
    ``fields`` its readers use: name -> a kind (:data:`TEXT`, :data:`NUMBER`, ...), a
    :class:`Table`, :class:`Rows` or :class:`OrAbsent`. Other fields pass unchecked."""

    name: str
    writer: str
    fields: dict


def _describe(kind) -> str:
    kind = kind.kind if isinstance(kind, OrAbsent) else kind
    return TABLE if isinstance(kind, Table) else "a list of tables" if isinstance(kind, Rows) else kind


def _check_fields(path, table: dict, fields: dict, where: str, record: RecordKind) -> None:
    for name, kind in fields.items():
        if name not in table:
            if isinstance(kind, OrAbsent):
                continue
            raise ParameterError(f"{path}: {where or 'the record'} lacks {name!r} ({_describe(kind)}): not a "
                                 f"{record.name} as {record.writer} writes it")
        _check_value(path, table[name], kind.kind if isinstance(kind, OrAbsent) else kind,
                     f"{where}.{name}" if where else name, record)


def _check_value(path, value, kind, where: str, record: RecordKind) -> None:
    if isinstance(kind, Rows):
        if not isinstance(value, list):
            raise ParameterError(f"{path}: {where} = {str(value)[:40]!r}, expected a list of tables")
        for i, row in enumerate(value):
            _check_value(path, row, Table(kind.fields), f"{where}[{i}]", record)
    elif isinstance(kind, Table):
        if not isinstance(value, dict):
            raise ParameterError(f"{path}: {where} = {str(value)[:40]!r}, expected a table")
        _check_fields(path, value, kind.fields, where, record)
    elif not _ADMITS[kind](value):
        raise ParameterError(f"{path}: {where} = {str(value)[:40]!r}, expected {kind}")


def read_record(path, kind: RecordKind) -> dict:
    """The JSON record at ``path``, checked against ``kind``'s fields: a file that cannot be
    read, is not JSON (truncated, another format), or lacks or mistypes a field raises one
    :class:`~mdroll.errors.ParameterError` naming the file, the field and what was expected."""
    try:
        record = json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise ParameterError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise ParameterError(f"{path}: a directory; give its {kind.name}'s JSON file") from None
    except OSError as exc:
        raise ParameterError(f"{path}: cannot be read ({exc.strerror or 'an input/output error'})") from None
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError):
        raise ParameterError(f"{path}: not a JSON {kind.name} (truncated, or another format)") from None
    if not isinstance(record, dict):
        raise ParameterError(f"{path}: not a {kind.name} (a JSON {type(record).__name__}, where {kind.writer} "
                             "writes a table)")
    _check_fields(path, record, kind.fields, "", kind)
    return record
