"""The on-disk ensemble cache: a CI that reruns the same checks reuses their ensembles.

An entry is named by :meth:`mdroll.EnsembleSpec.key`, a SHA-256 of the spec (parameters, seed,
realizations, algorithm, mode, boundary, window) and the mdroll version: ``<key>.npz`` holds the
:class:`~mdroll.EnsembleResult` (written by its ``save``), ``<key>.<what>.npz`` what a check
derived from the same ensemble (per-realization band sums, force differences).

Invalidation: a new mdroll version changes every key, so nothing older is read again; a changed
spec is another key. Entries are never updated in place: each is written atomically (a
temporary file beside it, then ``os.replace``) and a file that cannot be read is recomputed and
replaced. Old entries are never removed by mdroll: delete the directory to reclaim the space.
A development checkout keeps its version between commits: clear the cache (or ``--no-cache``)
after changing the force path there.
The device is not in the key: results agree across devices to rounding.

Location: ``cache_dir`` where given (``mdroll validate --cache-dir``, ``--mdroll-cache-dir`` of
the pytest plugin), else the environment variable ``MDROLL_CACHE_DIR``, else
``$XDG_CACHE_HOME/mdroll/ensembles`` (``~/.cache/mdroll/ensembles``).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..ensemble.result import EnsembleResult
from ..ensemble.spec import EnsembleSpec
from ..files import atomic_write
from ..errors import ParameterError

CACHE_ENV = "MDROLL_CACHE_DIR"


def default_cache_dir() -> Path:
    """``MDROLL_CACHE_DIR``, else ``$XDG_CACHE_HOME/mdroll/ensembles`` (``~/.cache`` without it)."""
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "mdroll" / "ensembles"


class EnsembleCache:
    """Results and derived arrays by spec key in ``directory`` (module docstring)."""

    def __init__(self, directory=None):
        self.directory = Path(directory) if directory is not None else default_cache_dir()
        if self.directory.exists() and not self.directory.is_dir():
            raise ParameterError(f"cache directory {self.directory} is a file")
        self.hits = 0
        self.misses = 0

    def path(self, spec: EnsembleSpec, what: str = "") -> Path:
        return self.directory / (spec.key() + (f".{what}" if what else "") + ".npz")

    def result(self, spec: EnsembleSpec, compute) -> EnsembleResult:
        """The cached result of ``spec``, or ``compute()``'s, stored."""
        path = self.path(spec)
        if path.is_file():
            try:
                result = EnsembleResult.load(path)
                self.hits += 1
                return result
            except ParameterError:
                pass  # unreadable: recomputed and replaced below
        self.misses += 1
        result = compute()
        self.directory.mkdir(parents=True, exist_ok=True)
        result.save(path)
        return result

    def arrays(self, spec: EnsembleSpec, what: str, compute) -> dict:
        """The cached arrays ``what`` of ``spec`` (a dict of NumPy arrays), or ``compute()``'s, stored."""
        path = self.path(spec, what)
        if path.is_file():
            try:
                with np.load(path) as data:
                    arrays = {k: data[k] for k in data.files}
                self.hits += 1
                return arrays
            except (OSError, ValueError, EOFError):
                pass
        self.misses += 1
        arrays = compute()
        self.directory.mkdir(parents=True, exist_ok=True)
        with atomic_write(path) as file:
            np.savez(file, **arrays)
        return arrays


class NoCache:
    """The stand-in for ``--no-cache``: computes every time, stores nothing."""

    hits = misses = 0

    def result(self, spec, compute):
        return compute()

    def arrays(self, spec, what, compute):
        return compute()
