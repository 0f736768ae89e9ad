"""An experiment's record: JSON with where, when and with what it was computed.

:func:`provenance` gives the keys every record carries: ``size``, ``seed``, ``parameters`` (the
rung's, JSON-ready), ``environment`` (:func:`mdroll.provenance.environment`: device and its name,
mdroll and library versions, platform, date) and ``git_commit``. :func:`write_json` writes a
record atomically.
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
from pathlib import Path

from ..devices import resolve_device
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
