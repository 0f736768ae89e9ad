"""Where checks get their ensembles: :func:`mdroll.run_specs` (the pipeline's own loop, in this
process or on a Dask cluster through ``runner``), an in-process memo and the on-disk cache.

Paired statistics (a ratio of band sums taken realization by realization, physics.md section 7)
need each realization's PSD, which an ensemble result averages away. :meth:`EnsembleSource.paired`
therefore runs a spec as one spec per realization (``spec.split(1)``, same seed and indices, so
the same lines as the whole spec), keeps each realization's PSD up to a cut-off wavenumber and
merges the results into the ensemble's (:meth:`mdroll.EnsembleResult.merge`: the same mean and
standard error as one run, to rounding). Two paired specs of the same seed and realizations
(say the direct and the tree force, or h0 and 2 h0) are then compared row by row.

Two statistics are not spectra of the pipeline and are taken here from the spec's lines
(:func:`mdroll.rough_lines`) and :func:`mdroll.contact_force`: the largest force difference of
two algorithms, and the per-realization PSD of a reference series of the lines (eq 48).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..devices import resolve_device
from ..ensemble.batching import default_batch
from ..forces.force import contact_force
from ..ensemble.lines import rough_lines
from ..ensemble.workers import progress_bar
from ..ensemble.result import EnsembleResult
from ..ensemble.spec import EnsembleSpec, run_specs
from ..ensemble.psd import array_rows, psd_rows, to_host, wavenumbers
from ..errors import ParameterError
from .cache import NoCache

#: Per-realization PSD rows are kept at least up to this many q_min (the bands the built-in
#: checks average over).
KEEP_ROWS_UP_TO = 8.5
#: Realizations run at once by :meth:`EnsembleSource.paired` (bounds the memory of their full spectra).
PAIRED_CHUNK = 16


@dataclass
class Paired:
    """An ensemble's result and the per-realization force PSD rows (N^2 m) of its first bins."""

    result: EnsembleResult
    rows: np.ndarray

    def band_sums(self, mask: np.ndarray) -> np.ndarray:
        """Per-realization sums (N^2 m) of the force PSD over the bins of ``mask``."""
        kept = self.rows.shape[1]
        if mask[kept:].any():
            raise ParameterError(f"band reaches beyond the kept bins (q <= {self.result.q[kept - 1]:.6g} rad/m)")
        return self.rows[:, mask[:kept]].sum(axis=1)


class EnsembleSource:
    """Ensemble results by spec, each computed once: from the memo, the cache or :func:`run_specs`.

    ``device``: where ensembles run ("auto", "cpu", "cuda", "cuda:N"); ``runner``: a runner for
    :func:`run_specs` (:class:`mdroll.distributed.DaskRunner`) or None; ``cache``: an
    :class:`~mdroll.validation.cache.EnsembleCache`, or None for none.
    """

    def __init__(self, device: str = "auto", runner=None, cache=None, progress: bool = False):
        self.device = device if runner is not None else resolve_device(device)
        self.runner = runner
        self.cache = cache if cache is not None else NoCache()
        self.progress = progress
        self._memo: dict = {}

    def _memoized(self, key, compute):
        if key not in self._memo:
            self._memo[key] = compute()
        return self._memo[key]

    def _run(self, specs: list[EnsembleSpec], progress: bool | None = None) -> list[EnsembleResult]:
        progress = self.progress if progress is None else progress
        return run_specs(specs, device=self.device, progress=progress, runner=self.runner)

    def result(self, spec: EnsembleSpec) -> EnsembleResult:
        """The ensemble result of ``spec``."""
        return self._memoized(spec.key(), lambda: self.cache.result(spec, lambda: self._run([spec])[0]))

    def paired(self, spec: EnsembleSpec, keep_q: float = 0.0) -> Paired:
        """The result of ``spec`` and its per-realization force PSD rows for q <= max(keep_q,
        KEEP_ROWS_UP_TO q_min) (rad/m), by one spec per realization (module docstring)."""
        q = wavenumbers(spec.params.n_points, spec.params.dx)
        kept = int(np.searchsorted(q, max(keep_q, KEEP_ROWS_UP_TO * spec.params.q_min), side="right"))

        def compute():
            merged, rows = None, []
            parts = spec.split(1)
            p = spec.params
            bar = progress_bar(len(parts), self.progress, f"{spec.algorithm} L={p.L:g} m H={p.H:g} h0={p.h0:g} m")
            for start in range(0, len(parts), PAIRED_CHUNK):
                results = self._run(parts[start:start + PAIRED_CHUNK], progress=False)  # one bar, not one a realization
                rows.extend(r.force_psd[:kept] for r in results)
                merged = EnsembleResult.merge(([merged] if merged is not None else []) + results)
                bar.update(len(results))
            bar.close()
            self._memo.setdefault(spec.key(), self.cache.result(spec, lambda: merged))
            return {"rows": np.array(rows)}

        rows = self._memoized((spec.key(), kept), lambda: self.cache.arrays(spec, f"rows{kept}", compute))["rows"]
        return Paired(self.result(spec), rows)

    def _line_batches(self, spec: EnsembleSpec):
        """The spec's lines, a batch at a time on this source's device."""
        device = resolve_device(self.device)
        batch = max(1, default_batch(spec.params, device) // 4)
        for part in spec.split(batch):
            indices = np.arange(part.first, part.first + part.realizations)
            yield rough_lines(spec.params, spec.seed, indices, device=device, roughness=spec.roughness), device

    def force_differences(self, spec: EnsembleSpec, algorithms, reference: str = "direct") -> dict:
        """max |F_algorithm - F_reference| (N) over the lines of ``spec`` at d0 on its boundary, for
        each of ``algorithms``, from one pass over the lines (the reference computed once)."""
        algorithms = tuple(algorithms)

        def compute():
            largest = dict.fromkeys(algorithms, 0.0)
            for lines, device in self._line_batches(spec):
                base = array_rows(contact_force(lines, spec.params, reference, spec.boundary, device=device), device)
                for name in algorithms:
                    force = array_rows(contact_force(lines, spec.params, name, spec.boundary, device=device), device)
                    largest[name] = max(largest[name], float(abs(force - base).max()))
            return {name: np.array(value) for name, value in largest.items()}

        what = "-".join(algorithms) + f"-vs-{reference}"
        arrays = self._memoized((spec.key(), what), lambda: self.cache.arrays(spec, what, compute))
        return {name: float(arrays[name]) for name in algorithms}

    def series_rows(self, spec: EnsembleSpec, name: str, series, keep_q: float) -> np.ndarray:
        """Per-realization PSD rows (q <= keep_q, rad/m) of ``series(params, lines)``, a reference
        series of each of the spec's lines (rows in the array module of the lines); ``name``
        names it in the cache."""
        kept = int(np.searchsorted(wavenumbers(spec.params.n_points, spec.params.dx), keep_q, side="right"))

        def compute():
            rows = [to_host(psd_rows(series(spec.params, array_rows(lines, device)), spec.params.dx, device)[:, :kept])
                    for lines, device in self._line_batches(spec)]
            return {"rows": np.concatenate(rows)}

        return self._memoized((spec.key(), name, kept),
                              lambda: self.cache.arrays(spec, f"{name}{kept}", compute))["rows"]
