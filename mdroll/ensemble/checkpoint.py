"""A run's accumulated state (:class:`RunTotals`) and its checkpoint file.

After every batch the pipeline can write the totals, with the run's identity, to a checkpoint
(atomically: a temporary file, then a rename); a resumed run loads them, refusing a checkpoint
of a different run, and continues where the batches stopped.
"""

from __future__ import annotations

import json
import math
import zipfile
from dataclasses import dataclass, field

import numpy as np

from .._version import __version__
from ..devices import warp
from ..files import atomic_write
from ..kernels.moments import LOST, SUM_DEVIATION, SUM_SQUARES
from ..errors import ParameterError
from ..params import Params
from .result import STAGES
from .psd import RunningMoments, array_module, to_host, wavenumbers

#: The checkpoint's file name in a run's output directory.
CHECKPOINT = "checkpoint.npz"


@dataclass
class RunTotals:
    """What a run has accumulated: PSD moments, force sums, contact-loss count, timings, and how
    many realizations (from the start of the list) are done."""

    force: RunningMoments | None = None
    accel: RunningMoments | None = None
    done: int = 0
    steps: int | None = None
    force_mean_sum: float = 0.0
    force_rms_sum: float = 0.0
    lost: int = 0
    timings: dict = field(default_factory=lambda: dict.fromkeys(STAGES, 0.0))
    batch: int = 0  # the run's batch size: the most realizations at once, which a resumed run keeps
    largest_batch: int = 0  # the most realizations a batch has held so far
    next_batch: int = 1  # the size planned for the next batch (a resumed run starts with it)

    def add_moments(self, rows: int, force_moments, accel_moments) -> None:
        """Merge a batch's PSD moments (:func:`~mdroll.ensemble.psd.psd_moments_of_batch`) of
        ``rows`` realizations, where they are (queued on the device: nothing waits)."""
        xp = array_module(force_moments)
        if self.force is None:
            bins = force_moments.shape[0]
            self.force, self.accel = RunningMoments(bins, xp), RunningMoments(bins, xp)
        else:  # a resumed run's moments come from the host: continue where the batches are
            self.force.move_to(xp)
            self.accel.move_to(xp)
        self.force.add_moments(rows, force_moments)
        self.accel.add_moments(rows, accel_moments)

    def add_sums(self, sums: np.ndarray, F_N: float) -> None:
        """Add a batch's force sums (host rows of :func:`~mdroll.ensemble.psd.series_sums`:
        deviations from ``F_N``, N) and count its realizations done."""
        mean_deviation = sums[:, SUM_DEVIATION] / self.steps
        variance = np.maximum(sums[:, SUM_SQUARES] / self.steps - mean_deviation**2, 0.0)
        self.force_mean_sum += float(np.sum(F_N + mean_deviation))
        self.force_rms_sum += float(np.sum(np.sqrt(variance)))
        self.lost += int(sums[:, LOST].sum())
        self.done += sums.shape[0]

    def spectra_on_host(self, params: Params, wait: bool = True) -> tuple[np.ndarray, ...]:
        """``(q, omega, force mean, its stderr, accel mean, its stderr)`` per bin (rad/m, rad/s,
        N^2 m, N^2 m, (m/s^2)^2 m, (m/s^2)^2 m), computed where the moments live and brought to
        the host in one copy, into page-locked memory on CUDA (the rows are views of it), not
        six separate copies and host arithmetic, nor a copy into pageable memory
        (docs/performance.md, "Spectra"). ``wait=False``: the copy is only queued
        (:func:`~mdroll.ensemble.psd.to_host`)."""
        force_mean, force_stderr = self.force.mean_and_stderr()
        accel_mean, accel_stderr = self.accel.mean_and_stderr()
        xp = array_module(force_mean)
        q = wavenumbers(self.steps, params.dx, xp)
        return tuple(to_host(xp.stack([q, q * params.v0, force_mean, force_stderr, accel_mean, accel_stderr]),
                             page_locked=True, wait=wait))

    def save(self, path, key: dict) -> None:
        """Write the totals, the batch size to resume with and the run's identity ``key`` to
        ``path`` atomically (:func:`mdroll.files.atomic_write`)."""
        meta = {**key, "done": self.done, "steps": self.steps, "force_mean_sum": self.force_mean_sum,
                "force_rms_sum": self.force_rms_sum, "lost": self.lost, "timings": self.timings, "count": self.force.count,
                "batch": self.batch, "largest_batch": self.largest_batch,
                "next_batch": self.next_batch,
                "versions": {"mdroll": __version__, "warp": warp().config.version, "numpy": np.__version__}}
        with atomic_write(path) as file:
            np.savez(file, meta=json.dumps(meta), force_mean=self.force.mean, force_m2=self.force.m2,
                     accel_mean=self.accel.mean, accel_m2=self.accel.m2)

    @classmethod
    def load(cls, path, key: dict) -> "RunTotals":
        """The totals saved at ``path``; refuses a checkpoint of a different run, naming what differs."""
        meta, arrays = read_checkpoint(path)
        differences = [f"{k}: {meta['params'][k]!r} (checkpoint) vs {v!r} (now)"
                       for k, v in key["params"].items() if meta["params"].get(k) != v]
        differences += [f"{k}: {_short(meta.get(k))} (checkpoint) vs {_short(v)} (now)"
                        for k, v in key.items() if k != "params" and meta.get(k) != v]
        if differences:
            raise ParameterError(f"cannot resume {path}: the run differs from the checkpoint: " + "; ".join(differences))
        totals = cls(done=meta["done"], steps=meta["steps"], force_mean_sum=meta["force_mean_sum"],
                     force_rms_sum=meta["force_rms_sum"], lost=meta["lost"], timings=meta["timings"],
                     batch=meta["batch"], largest_batch=meta["largest_batch"],
                     next_batch=meta["next_batch"])
        totals.force, totals.accel = RunningMoments(arrays["force_mean"].size), RunningMoments(arrays["accel_mean"].size)
        totals.force.merge(meta["count"], arrays["force_mean"], arrays["force_m2"])
        totals.accel.merge(meta["count"], arrays["accel_mean"], arrays["accel_m2"])
        return totals


#: What a checkpoint's metadata and arrays must hold.
CHECKPOINT_META = ("params", "seed", "realizations", "done", "steps", "force_mean_sum", "force_rms_sum", "lost",
                   "timings", "count", "batch", "largest_batch", "next_batch", "versions")
CHECKPOINT_ARRAYS = ("force_mean", "force_m2", "accel_mean", "accel_m2")


def read_checkpoint(path) -> tuple[dict, dict]:
    """The metadata (run identity, progress, batch, versions) and the accumulator arrays of a
    checkpoint. Refused with a :class:`ParameterError` naming the file: one that cannot be read
    (empty, truncated, not a checkpoint), one written by another mdroll version (its
    realizations and spectra need not be this version's), one holding NaN or infinity."""
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            arrays = {k: data[k] for k in CHECKPOINT_ARRAYS}
        missing = [k for k in CHECKPOINT_META if k not in meta]
    except (OSError, EOFError, ValueError, KeyError, TypeError, AttributeError, zipfile.BadZipFile):
        raise ParameterError(f"checkpoint {path} cannot be read: it is empty, truncated or not an mdroll checkpoint; "
                             "start the run again without --resume") from None
    if missing:
        raise ParameterError(f"checkpoint {path} lacks {missing}: not a checkpoint of this mdroll; start the run again")
    written_by = meta["versions"].get("mdroll")
    if written_by != __version__:
        raise ParameterError(f"checkpoint {path} was written by mdroll {written_by}, this is {__version__}: a run is "
                             "resumed by the version that started it (realizations and spectra may differ between "
                             "versions); finish it with that version or start again")
    sums = [meta[k] for k in ("force_mean_sum", "force_rms_sum")]
    bad = [k for k, a in arrays.items() if not np.isfinite(a).all()]
    if bad or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in sums):
        raise ParameterError(f"checkpoint {path} holds NaN or infinity (in {bad or 'its force sums'}): it cannot be "
                             "continued; start the run again")
    return meta, arrays


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
