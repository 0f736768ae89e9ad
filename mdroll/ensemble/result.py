"""The result of an ensemble run: its averaged spectra, provenance, file format and summary."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._version import __version__
from ..params import ParameterError, Params
from .spectra import RunningMoments

#: The stages of a run whose times a result reports, in the order a batch passes them.
STAGES = ("generate", "build", "force", "response", "spectra")


@dataclass
class EnsembleResult:
    """Ensemble-averaged force and acceleration spectra (physics.md section 6).

    Attributes
    ----------
    q : (K,) wavenumbers q_k = 2 pi k / (S dx), rad/m.
    omega : (K,) angular frequencies q v0, rad/s.
    force_psd, force_psd_stderr : (K,) mean two-sided PSD of F over the ensemble and its standard
        error, N^2 m (per rad/m; divide by v0 for per rad/s).
    accel_psd, accel_psd_stderr : (K,) the same for the acceleration, (m/s^2)^2 m.
    force_rms : RMS of F - mean F averaged over realizations, N.
    force_mean : mean force, N.
    contact_lost_steps : steps with F = 0 (the wheel off the rail) summed over the ensemble.
    timings : seconds per stage (:data:`STAGES`): on CUDA the device's time, from CUDA events
        around each stage; on the CPU wall time.
    batch : realizations per batch; realizations : the realization indices, in order.

    Plots: :func:`mdroll.plotting.plot_psd`.
    """

    q: np.ndarray
    omega: np.ndarray
    force_psd: np.ndarray
    force_psd_stderr: np.ndarray
    accel_psd: np.ndarray
    accel_psd_stderr: np.ndarray
    n_real: int
    params: Params
    seed: int
    algorithm: str
    mode: str
    boundary: str
    device: str
    steps: int
    force_mean: float
    force_rms: float
    contact_lost_steps: int = 0
    timings: dict = field(default_factory=dict)
    batch: int = 0
    realizations: list = field(default_factory=list)

    def save(self, path) -> Path:
        """Write an ``.npz`` with the spectra, the parameters and the provenance."""
        path = Path(path)
        meta = {
            "params": self.params.as_dict(),
            **{k: getattr(self, k) for k in ("n_real", "seed", "algorithm", "mode", "boundary", "device", "steps",
                                               "force_mean", "force_rms", "contact_lost_steps", "timings", "batch",
                                               "realizations")},
            "mdroll_version": __version__,
        }
        np.savez(path, q=self.q, omega=self.omega, force_psd=self.force_psd, force_psd_stderr=self.force_psd_stderr,
                 accel_psd=self.accel_psd, accel_psd_stderr=self.accel_psd_stderr, meta=json.dumps(meta))
        return path

    @classmethod
    def load(cls, path) -> "EnsembleResult":
        with np.load(path) as data:
            meta = json.loads(str(data["meta"]))
            arrays = {k: data[k] for k in ("q", "omega", "force_psd", "force_psd_stderr", "accel_psd", "accel_psd_stderr")}
        meta.pop("mdroll_version", None)
        return cls(params=Params(**meta.pop("params")), **arrays, **meta)

    @classmethod
    def merge(cls, results: list["EnsembleResult"]) -> "EnsembleResult":
        """One result from ensembles of disjoint realizations of the same run (say, one per
        process): per-bin means and variances merged exactly (Chan et al.)."""
        first = results[0]
        same = ("params", "seed", "algorithm", "mode", "boundary", "steps")
        for other in results[1:]:
            differ = [k for k in same if getattr(other, k) != getattr(first, k)]
            if differ:
                raise ParameterError(f"cannot merge results that differ in {differ}")
        indices = [i for r in results for i in r.realizations]
        if len(set(indices)) != len(indices):
            raise ParameterError("cannot merge results that share realizations (each would count twice)")
        moments = {}
        for name in ("force_psd", "accel_psd"):
            m = RunningMoments(first.q.size)
            for r in results:
                err = getattr(r, name + "_stderr")
                m.merge(r.n_real, getattr(r, name), err**2 * r.n_real * (r.n_real - 1))
            moments[name] = m
        n = sum(r.n_real for r in results)
        return cls(
            q=first.q, omega=first.omega, force_psd=moments["force_psd"].mean, force_psd_stderr=moments["force_psd"].stderr,
            accel_psd=moments["accel_psd"].mean, accel_psd_stderr=moments["accel_psd"].stderr, n_real=n,
            params=first.params, seed=first.seed, algorithm=first.algorithm, mode=first.mode, boundary=first.boundary,
            device=",".join(sorted({r.device for r in results})), steps=first.steps,
            force_mean=sum(r.force_mean * r.n_real for r in results) / n,
            force_rms=sum(r.force_rms * r.n_real for r in results) / n,
            contact_lost_steps=sum(r.contact_lost_steps for r in results),
            timings={k: sum(r.timings.get(k, 0.0) for r in results) for k in STAGES}, batch=first.batch,
            realizations=indices,
        )


def result_summary(result: EnsembleResult) -> dict:
    """JSON-ready summary: parameters, derived values, RMS force, timings, device."""
    p = result.params
    return {
        "params": p.as_dict(),
        "derived": {k: {"value": v, "unit": u} for k, (v, u, _) in p.derived().items()},
        "n_real": result.n_real, "seed": result.seed, "algorithm": result.algorithm, "mode": result.mode,
        "boundary": result.boundary, "device": result.device, "steps": result.steps,
        "force_mean_N": result.force_mean, "force_rms_N": result.force_rms,
        "contact_lost_steps": result.contact_lost_steps,
        "timings_s": result.timings,
    }
