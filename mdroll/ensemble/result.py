"""The result of an ensemble run: its averaged spectra, provenance, file format and summary."""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._version import __version__
from ..checks import first_negative_or_nonfinite
from ..files import atomic_write
from ..errors import ParameterError
from ..params import Params
from .psd import RunningMoments, wavenumbers
from .realizations import COUNT_KEY, read_params
from .resolution import estimator_name, resolution
from .vibration import VIBRATION, rail_form, structures_of, vibration_spectra

#: The stages of a run whose times a result reports, in the order a batch passes them.
STAGES = ("generate", "build", "force", "response", "spectra")
#: The arrays of a spectra file, and the fields its metadata holds beside the parameters.
RESULT_ARRAYS = ("q", "omega", "force_psd", "force_psd_stderr", "accel_psd", "accel_psd_stderr")
#: The masks a spectra file holds beside them (True: a bin the record cannot resolve,
#: :mod:`mdroll.ensemble.resolution`); derived from the spectra, so not read back.
RESULT_MASKS = ("force_unresolved", "accel_unresolved")
RESULT_META = ("n_real", "seed", "algorithm", "mode", "boundary", "window", "device", "steps", "force_mean",
               "force_rms", "contact_lost_steps", "timings", "batch", "realizations")
#: The run settings merged results must share (besides their physical parameters).
MERGE_SAME = ("seed", "algorithm", "mode", "boundary", "window", "steps", "track", "wheel")
#: The fields of a coupled run on a track (None for the rigid track and wheel: then absent from its files).
STRUCTURES = ("track", "wheel")


def compatible_versions(a: str, b: str) -> bool:
    """Whether spectra written by mdroll versions ``a`` and ``b`` may be merged: the same release
    series (major.minor), in which the generator and the spectra's definitions do not change."""
    return a.split(".")[:2] == b.split(".")[:2]


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
    batch : the largest batch (realizations at once) the run used; realizations : the
        realization indices, in order. n_real: their count, the run's (``params`` holds the
        physics and the grid alone).
    window : whether a Hann window was applied before the FFTs (None: unknown, a file written
        before the window was recorded); results differing in it are never merged.
    resolution : the bins this record and estimator cannot resolve (:mod:`mdroll.ensemble.resolution`).
    track, wheel : the fields of the :class:`~mdroll.track.Track` and :class:`~mdroll.wheel.Wheel`
        of a coupled run on a track (None for the rigid ones): its wheel and rail vibration
        spectra are :meth:`vibration` (:mod:`mdroll.ensemble.vibration`), and ``accel_psd`` is
        the wheel's acceleration at the contact.

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
    window: bool | None = False
    mdroll_version: str = __version__
    track: dict | None = None
    wheel: dict | None = None

    @property
    def resolution(self):
        """The unresolved bins of both spectra (:func:`mdroll.ensemble.resolution.resolution`)."""
        return resolution(self.omega, self.force_psd, self.accel_psd, self.params.omega_0, self.window, self.mode)

    def vibration(self) -> dict:
        """The wheel's and the rail's velocity PSDs and standard errors of a run on a track
        (:func:`mdroll.ensemble.vibration.vibration_spectra`); empty for the rigid track and wheel."""
        return vibration_spectra(self) if self.track or self.wheel else {}

    def save(self, path) -> Path:
        """Write an ``.npz`` with the spectra, the parameters (:meth:`Params.as_dict`; the
        count is ``n_real``, beside them) and the provenance, atomically (:func:`mdroll.files.atomic_write`).
        A name without ``.npz`` gets it appended, as :func:`numpy.savez` does."""
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_name(path.name + ".npz")
        meta = {"params": self.params.as_dict(), **{k: getattr(self, k) for k in RESULT_META},
                "mdroll_version": __version__, **{k: getattr(self, k) for k in STRUCTURES if getattr(self, k)}}
        flags = self.resolution
        masks = {f"{quantity}_unresolved": flags.mask(quantity) for quantity in ("force", "accel")}
        # derived from the force spectra, so not read back
        vibration = {f"{name}_psd{tail}": values for name, pair in self.vibration().items()
                     for tail, values in zip(("", "_stderr"), pair)}
        with atomic_write(path) as file:
            np.savez(file, **{k: getattr(self, k) for k in RESULT_ARRAYS}, **masks, **vibration, meta=json.dumps(meta))
        return path

    @classmethod
    def load(cls, path) -> "EnsembleResult":
        """The result saved at ``path`` by :meth:`save`; anything else (a truncated or foreign
        file, a checkpoint) is refused with a :class:`ParameterError` naming the file. A file that
        holds the count inside its parameters (``n_real``, as files once did) is read with it as
        the result's ``n_real``."""
        try:
            with np.load(path, allow_pickle=False) as data:
                meta = json.loads(str(data["meta"]))
                if "done" in meta:
                    raise ParameterError(f"{path} is a checkpoint of an unfinished run, not its spectra: finish the "
                                         "run with mdroll run --resume DIR first")
                arrays = {k: data[k] for k in RESULT_ARRAYS}
            meta.setdefault("window", None)  # files from before the window was recorded
            meta.setdefault("mdroll_version", "unknown")
            params, count = read_params(meta.pop("params"))
            if count is not None and meta.setdefault("n_real", count) != count:
                raise ParameterError(f"{COUNT_KEY} = {count} in its parameters but {meta['n_real']!r} beside them")
            result = cls(params=params, **arrays, **meta)
        except ParameterError as exc:
            raise ParameterError(f"{path}: {exc}") from None
        except (OSError, EOFError, ValueError, KeyError, TypeError, AttributeError, zipfile.BadZipFile):
            raise ParameterError(f"{path} is not an mdroll spectra file (as written by mdroll run or merge): it is "
                                 "truncated, corrupt or of another kind") from None
        _check_content(result, path)
        return result

    @classmethod
    def merge(cls, results: list["EnsembleResult"]) -> "EnsembleResult":
        """One result from ensembles of disjoint realizations of the same run (say, one per
        process, of any sizes): per-bin means and variances merged exactly (Chan et al.).
        Results that differ in a parameter (other than their count) or a run setting are
        refused, naming the field and both values."""
        if isinstance(results, EnsembleResult) or not isinstance(results, (list, tuple)):
            raise ParameterError(f"results must be a list of mdroll.EnsembleResult, got {type(results).__name__}")
        if not results:
            raise ParameterError("merge needs at least one result, got none")
        for number, other in enumerate(results, start=1):
            if not isinstance(other, EnsembleResult):
                raise ParameterError(f"results: item {number} is a {type(other).__name__}, not an mdroll.EnsembleResult")
            _check_content(other, f"result {number}")
        return cls.merge_own(results)

    @classmethod
    def merge_own(cls, results: list["EnsembleResult"]) -> "EnsembleResult":
        """:meth:`merge` of results that runs of this package made in memory (the Dask runner's
        units, on the workers and on the client): the same exact merge and the same refusals of
        results that do not belong together (parameters, grids, versions, shared realizations),
        without re-checking each one's content, which :meth:`load` and :meth:`merge` check for
        results of unknown origin (about 50 ms a result at 2^20 springs)."""
        first = results[0]
        physics = first.params.as_dict()
        for number, other in enumerate(results[1:], start=2):
            theirs = other.params.as_dict()
            differ = [f"{k}: {v!r} vs {theirs[k]!r}" for k, v in physics.items() if theirs[k] != v]
            differ += [f"{k}: {getattr(first, k)!r} vs {getattr(other, k)!r}" for k in MERGE_SAME
                       if getattr(other, k) != getattr(first, k)]
            if differ:
                raise ParameterError(f"cannot merge results 1 and {number}: they differ in " + "; ".join(differ))
        for number, other in enumerate(results, start=1):
            if other.q.shape != first.q.shape or not np.array_equal(other.q, first.q):
                raise ParameterError(f"cannot merge results 1 and {number}: their wavenumber grids q differ")
            if not compatible_versions(other.mdroll_version, first.mdroll_version):
                raise ParameterError(f"cannot merge results 1 and {number}: written by mdroll {first.mdroll_version} "
                                     f"and {other.mdroll_version}, whose spectra may differ; rerun one of them")
        indices = np.concatenate([np.asarray(r.realizations, dtype=np.int64) for r in results])
        unique, counts = np.unique(indices, return_counts=True)
        if unique.size != indices.size:
            shared = unique[counts > 1][:5].tolist()
            raise ParameterError(f"cannot merge results that share realizations {shared} (each would count twice)")
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
            timings={k: sum(r.timings.get(k, 0.0) for r in results) for k in STAGES},
            batch=max(r.batch for r in results), realizations=indices.tolist(), window=first.window, track=first.track,
            wheel=first.wheel,
        )


def _check_content(result: EnsembleResult, where) -> None:
    """Refuse a result whose content contradicts itself, naming ``where`` (its file) and the
    field: a realization list absent or not of ``n_real`` distinct indices >= 0, arrays not of
    the grid's length, a spectrum or standard error that is not finite and >= 0."""
    n = result.n_real
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ParameterError(f"{where}: n_real = {n!r}, expected a positive integer")
    indices = result.realizations
    if not isinstance(indices, (list, tuple, range)) or len(indices) != n:
        count = len(indices) if isinstance(indices, (list, tuple, range)) else "no"
        raise ParameterError(f"{where}: its realization list has {count} indices but n_real = {n}; the file is "
                             "damaged or was edited (a merge needs each part's realizations)")
    kinds = set(map(type, indices))  # vectorized checks: a merge may hold ~10^5 indices
    if any(k is bool or not issubclass(k, (int, np.integer)) for k in kinds) \
            or min(indices, default=0) < 0 or np.unique(np.asarray(indices, dtype=np.int64)).size != n:
        raise ParameterError(f"{where}: its realization list must hold {n} distinct integers >= 0")
    steps = result.steps
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 2:
        raise ParameterError(f"{where}: steps = {steps!r}, expected an integer >= 2")
    grid = wavenumbers(steps, result.params.dx)
    size = grid.shape
    for name in RESULT_ARRAYS:
        values = np.asarray(getattr(result, name))
        if values.shape != size or values.ndim != 1 or values.dtype.kind != "f":
            raise ParameterError(f"{where}: {name} has shape {values.shape}, expected {size} floats (one per wavenumber)")
        expected = {"q": grid, "omega": grid * result.params.v0}.get(name)
        if expected is not None and not np.allclose(values, expected, rtol=1e-12, atol=0.0):
            raise ParameterError(f"{where}: {name} is not the grid of {steps} steps of dx = {result.params.dx!r} m "
                                 f"(q_k = 2 pi k / (steps dx){', omega = q v0' if name == 'omega' else ''})")
        i = first_negative_or_nonfinite(values)
        if i is not None:
            raise ParameterError(f"{where}: {name}[{i}] = {values[i]!r}; a spectrum and its standard error must be "
                                 "finite and >= 0")


def result_summary(result: EnsembleResult) -> dict:
    """JSON-ready summary: parameters, derived values, the run's settings (realization count,
    window, the estimator's name, the largest batch used), the unresolved bins (``resolution``:
    which and why), RMS force, timings, device, mdroll version."""
    p = result.params
    return {
        "params": p.as_dict(),
        "derived": {k: {"value": v, "unit": u} for k, (v, u, _) in p.derived().items()},
        "n_real": result.n_real, "seed": result.seed, "algorithm": result.algorithm, "mode": result.mode,
        "boundary": result.boundary, "window": result.window, "estimator": estimator_name(result.window),
        "resolution": result.resolution.summary(result.omega), "batch": result.batch, "device": result.device,
        "steps": result.steps, "mdroll_version": __version__,
        "force_mean_N": result.force_mean, "force_rms_N": result.force_rms,
        "contact_lost_steps": result.contact_lost_steps,
        "timings_s": result.timings,
        **_structures_summary(result),
    }


def _structures_summary(result: EnsembleResult) -> dict:
    """A run on a track: its track and wheel, where the wheel stands, and what the vibration
    spectra are (nothing for the rigid track and wheel)."""
    if not (result.track or result.wheel):
        return {}
    track, _ = structures_of(result)
    fit = rail_form(track).error_db if track.support != "rigid" else 0.0
    return {"track": result.track, "wheel": result.wheel, "vibration": {
        "quantities": [name for name in VIBRATION if name in result.vibration()],
        "definition": "velocity at the contact, S_v = omega^2 |alpha|^2 S_F per bin (mdroll.ensemble.vibration): "
                      "alpha the stepped rail state space above a sleeper and the wheel's receptance; accel_psd "
                      "is the wheel's acceleration at the contact",
        "rail_fit_error_dB": fit}}
