"""Output files: atomic writes (a file is either the old one or the complete new one, never a
part), TOML input with one-line errors, and values made JSON-ready."""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
import tomllib
from pathlib import Path

import numpy as np

# the process's umask, read once (os.umask can only be read by setting it): the permissions an
# ordinary open() would give, for mkstemp's private 0600 temporary file
_UMASK = os.umask(0)
os.umask(_UMASK)


@contextlib.contextmanager
def atomic_write(path, mode: str = "wb"):
    """Open a temporary file beside ``path`` for writing (``mode`` "wb" or "w"), and on a normal
    exit flush it to disk and rename it over ``path`` (``os.replace``: atomic on POSIX). On an
    exception, or a kill before the rename, ``path`` is untouched and the temporary file
    (``.<name>.<random>.tmp``) is removed or left aside, never read as an output."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, 0o666 & ~_UMASK)
        with os.fdopen(fd, mode) as file:
            yield file
            file.flush()
            os.fsync(file.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def read_toml(path, what: str, error: type[Exception] = ValueError) -> dict:
    """The tables of the TOML file ``path``, or ``error`` with one line naming the file as
    ``what`` (e.g. "config file") when it does not exist or is not valid TOML (or not UTF-8)."""
    file = Path(path)
    if not file.is_file():
        raise error(f"{what} {str(path)!r} does not exist")
    try:
        return tomllib.loads(file.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise error(f"{what} {path}: not valid TOML ({exc})") from None


def jsonable(value):
    """``value`` as JSON values: NumPy scalars and arrays as numbers and lists, tuples as lists,
    dict keys as strings, non-finite floats (nan, inf) as null."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (np.floating, float)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value
