"""Output files: atomic writes (a file is either the old one or the complete new one, never a
part), TOML input with one-line errors, and values made JSON-ready."""

from __future__ import annotations

import contextlib
import glob
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
    (``.<name>.<random>.tmp``) is removed or left aside (:func:`remove_stale_temporaries`), never
    read as an output. An OS error (a full disk, a name too long, a directory at ``path``) names
    ``path``, not the temporary file."""
    path = Path(path)
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    except OSError as exc:
        raise type(exc)(exc.errno, exc.strerror, str(path)) from None
    try:
        os.fchmod(fd, 0o666 & ~_UMASK)
        with os.fdopen(fd, mode) as file:
            yield file
            file.flush()
            os.fsync(file.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError) and exc.errno is not None and not isinstance(exc, BrokenPipeError):
            raise type(exc)(exc.errno, exc.strerror, str(path)) from None
        raise


def save_figure(fig, target, **options) -> None:
    """Save the Matplotlib figure ``fig`` to ``target``: a binary file (as PNG), or a path, written
    through :func:`atomic_write` in the format its suffix names (PNG without one); ``options``
    go to ``fig.savefig``."""
    if hasattr(target, "write"):
        fig.savefig(target, **{"format": "png", **options})
        return
    path = Path(target)
    with atomic_write(path) as file:
        fig.savefig(file, **{"format": path.suffix.lstrip(".").lower() or "png", **options})


def remove_stale_temporaries(path) -> None:
    """Remove the temporary files that killed :func:`atomic_write` calls of ``path`` left beside
    it; only where no other process can be writing ``path`` (a locked run directory)."""
    path = Path(path)
    for stale in path.parent.glob(f".{glob.escape(path.name)}.*.tmp"):
        with contextlib.suppress(OSError):
            stale.unlink()


def read_toml(path, what: str, error: type[Exception] = ValueError) -> dict:
    """The tables of the TOML file ``path``, or ``error`` with one line naming the file as
    ``what`` (e.g. "config file") when it does not exist or is not valid TOML (or not UTF-8)."""
    file = Path(path)
    if not file.is_file():
        raise error(f"{what} {str(path)!r} does not exist")
    try:
        return tomllib.loads(file.read_text())
    except UnicodeDecodeError:
        raise error(f"{what} {path}: not a text file (not UTF-8); TOML is UTF-8 text") from None
    except tomllib.TOMLDecodeError as exc:  # its message names the line and column
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
