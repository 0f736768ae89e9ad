"""What a worker ships of its units: a :data:`Part`, its spectra in one contiguous array.

A unit's :class:`~mdroll.ensemble.result.EnsembleResult` becomes a part on its worker
(:func:`part_of`): the per-bin means and standard errors of the force and acceleration PSDs as the
rows of one (4, bins) float64 array, which Dask sends as one frame (placed first in the part's
tuple: Dask serializes a tuple's items apart when its first is an array, and pickles the
whole otherwise), beside the result without its arrays and its realizations as ranges. Parts merge
exactly (:class:`PartSum`, :func:`merge_parts`) and give the result back (:func:`result_of`).
"""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np

from ..ensemble.psd import RunningMoments, wavenumbers
from ..ensemble.result import EnsembleResult
from ..errors import ParameterError

#: The rows of a part's spectra array, per bin: each PSD's mean over the part's realizations and
#: its standard error.
SPECTRA = ("force_psd", "force_psd_stderr", "accel_psd", "accel_psd_stderr")
#: A part of a spec's result as the workers hold and ship it: ``(spectra, bare, spans)``, the
#: (4, bins) float64 array of :data:`SPECTRA` first, the result's other fields (an
#: :class:`EnsembleResult` whose arrays are empty and whose realizations are in ``spans``) and its
#: realizations as sorted, disjoint ``(first, count)`` ranges.
Part = tuple
_EMPTY = np.empty(0)


def part_of(result: EnsembleResult, first: int) -> Part:
    """The :data:`Part` of a result of the consecutive realizations from ``first``."""
    bare = dataclasses.replace(result, q=_EMPTY, omega=_EMPTY, **dict.fromkeys(SPECTRA, _EMPTY), realizations=[])
    return spectra_rows(result), bare, ((first, result.n_real),)


def spectra_rows(result: EnsembleResult) -> np.ndarray:
    """The (4, bins) array of the result's :data:`SPECTRA`: a view where they are consecutive
    rows of one contiguous buffer, as a run returns them (its spectra come to the host in one
    copy, page-locked on CUDA: :meth:`~mdroll.ensemble.checkpoint.RunTotals.spectra_on_host`),
    else a stacked copy. The view spares the worker a copy of every bin into fresh memory before
    the part is sent."""
    rows = [getattr(result, name) for name in SPECTRA]
    first, buffer = rows[0], rows[0].base  # NumPy's base: the array that holds the rows' memory
    if (isinstance(buffer, np.ndarray) and buffer.flags.c_contiguous and buffer.dtype == first.dtype
            and all(row.base is buffer and row.shape == first.shape and row.strides == (row.itemsize,)
                    for row in rows)):
        flat = buffer.reshape(-1)
        if [row.ctypes.data for row in rows] == [first.ctypes.data + k * first.nbytes for k in range(len(rows))]:
            start = (first.ctypes.data - flat.ctypes.data) // flat.itemsize
            return flat[start:start + len(rows) * first.size].reshape(len(rows), first.size)
    return np.stack(rows)


class PartSum:
    """Parts of one spec merged into one (:meth:`part`): their spectra's means and variances in one
    :class:`~mdroll.ensemble.psd.RunningMoments` over both spectra's bins at once (Chan et al.,
    exact, as the batches of one run), their other fields and the refusals of parts that do not
    belong together by :meth:`EnsembleResult.merge_own` on the arrayless results. ``eager``:
    each part is merged as it is added (the client's, while other units still run); else at the
    end, and a single part is kept as it is."""

    def __init__(self, eager: bool = False):
        self.eager = eager
        self.pending: list = []
        self.moments = None
        self.bares: list = []
        self.spans: list = []

    def add(self, part: Part) -> None:
        self.pending.append(part)
        if self.eager:
            self._merge_pending()

    def _merge_pending(self) -> None:
        for spectra, bare, spans in self.pending:
            EnsembleResult.merge_own(self.bares[:1] + [bare])  # refuses parts of another run, naming why
            if self.moments is None:
                self.moments = RunningMoments(spectra[0::2].shape)  # the force's and acceleration's bins
            n = bare.n_real
            self.moments.merge(n, spectra[0::2], spectra[1::2] ** 2 * n * (n - 1))
            self.bares.append(bare)
            self.spans.extend(spans)
        self.pending = []

    def part(self) -> Part:
        if not self.bares and len(self.pending) == 1:
            return self.pending[0]
        self._merge_pending()
        spans = tuple(sorted(self.spans))
        for (first, count), (after, _) in zip(spans, spans[1:]):
            if first + count > after:
                raise ParameterError(f"cannot merge parts that share realization {after} (it would count twice)")
        mean, stderr = self.moments.mean_and_stderr()
        spectra = np.empty((len(SPECTRA), mean.shape[1]))
        spectra[0::2], spectra[1::2] = mean, stderr
        return spectra, EnsembleResult.merge_own(self.bares), spans


def merge_parts(*parts: Part) -> Part:
    """One part of several of one spec (one is itself; :class:`PartSum`): the reduction's task on
    the workers."""
    total = PartSum()
    for part in parts:
        total.add(part)
    return total.part()


def result_of(part: Part) -> EnsembleResult:
    """The :class:`EnsembleResult` of a part: its grid (as the run computes it), spectra and
    realizations in order."""
    spectra, bare, spans = part
    q = wavenumbers(bare.steps, bare.params.dx)
    return dataclasses.replace(bare, q=q, omega=q * bare.params.v0, **dict(zip(SPECTRA, spectra)),
                               realizations=list(itertools.chain.from_iterable(range(f, f + n) for f, n in spans)))
