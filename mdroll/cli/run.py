"""``mdroll run``: an ensemble's spectra, summary, band levels and plots; resumable, and on a Dask
cluster with ``--workers``/``--scheduler``."""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

from .. import plotting
from ..devices import resolve_device
from ..distributed import saved_specs
from ..arguments import check_integer
from ..forces.registry import (ALGORITHMS, DEFAULT_ALGORITHMS, REGISTRY, algorithm_entry, coupled_entry,
                               default_algorithm)
from ..ensemble.batching import check_count_fits, check_run_fits, realization_bytes
from ..ensemble.checkpoint import CHECKPOINT, read_checkpoint
from ..ensemble.lines import MAX_INDEX, check_seed
from ..ensemble.pipeline import run_ensemble
from ..ensemble.realizations import DEFAULT_REALIZATIONS
from ..ensemble.result import result_summary
from ..ensemble.spec import EnsembleSpec
from ..ensemble.validity import parameter_concerns, result_concerns
from ..errors import SchedulerLost, UsageError
from ..files import atomic_write, remove_stale_temporaries
from ..railway.report import write_band_outputs
from .common import (build_params, build_structures, check_output, cluster_options, cluster_runner, device_option,
                     format_value, lock, output_dir, output_options, param_options, rigid_wheel_mass)

#: What ``run`` and ``merge`` write; ``--force`` removes the old ones first, so that a finished
#: run's files never mix with a new run's.
RUN_OUTPUTS = ("spectra.npz", "summary.json", "accel_psd.png", "force_psd.png", "bands.csv", "bands.png")
#: Settings of a run besides its parameters, and their defaults (a resumed run's are its checkpoint's).
RUN_DEFAULTS = {"seed": 0, "algorithm": None, "mode": "decoupled", "boundary": "open", "window": True}


def add_parser(sub) -> None:
    p = sub.add_parser("run", help="run an ensemble and write spectra, summary and plots")
    param_options(p)
    p.add_argument("--realizations", type=int, help=f"number of realizations (default {DEFAULT_REALIZATIONS}); "
                   "wins over an n_real of --preset, --config or --set")
    p.add_argument("--first", type=int, help="index of the first realization (default 0): split an ensemble "
                   "across processes, then `mdroll merge`")
    p.add_argument("--seed", type=int, help="master seed (default 0)")
    p.add_argument("--algorithm", choices=ALGORITHMS, help="default: " + ", ".join(
        f"{name} ({mode})" for mode, name in DEFAULT_ALGORITHMS.items()) + "; " + "; ".join(
        f"{entry.name}: {entry.description}, {entry.complexity.text}" for entry in REGISTRY.values()))
    p.add_argument("--mode", choices=["decoupled", "coupled"], help="default decoupled")
    p.add_argument("--boundary", choices=["open", "periodic"], help="default open")
    device_option(p)
    p.add_argument("--batch", type=int, help="realizations per batch (default: from free memory)")
    p.add_argument("--memory-limit", type=float, metavar="GIB", help="cap the memory batches are sized from (GiB)")
    estimator = p.add_mutually_exclusive_group()
    estimator.add_argument("--window", action="store_true", default=None, help="Hann window before the FFT, "
                           "normalized by mean w^2 (the default)")
    estimator.add_argument("--no-window", dest="window", action="store_false", help="no window: the open record "
                           "leaks the resonance and the high band into other bins (flagged in the outputs)")
    estimator.add_argument("--thesis-estimator", action="store_true", help="the thesis's setup: open boundary, no "
                           "window (for reproducing its figures; the outputs flag the bins it cannot resolve)")
    p.add_argument("--resume", metavar="DIR", help="continue the interrupted run in DIR (its checkpoint.npz); "
                   "its outputs go there too")
    p.add_argument("--force-physics", action="store_true", help="run parameters outside the model's validity "
                   "(h0 not small against d0, a time step that shifts the resonance); the summary lists why")
    cluster_options(p)
    output_options(p)


def execute(args) -> int:
    if args.workers is not None or args.scheduler is not None:
        return _run_distributed(args)
    device = resolve_device(args.device)
    if args.resume:
        out = _resumed_folder(args)
        if not (out / CHECKPOINT).is_file():
            raise UsageError(f"--resume {args.resume}: no {CHECKPOINT} there to continue from")
        lock(out, "--resume")
        meta, _ = read_checkpoint(out / CHECKPOINT)
        # the checkpoint's run, with anything given on the command line on top (compared when resuming)
        params, count = build_params(args, base=meta["params"])
        settings = _settings(args, meta)
        realizations = meta["realizations"] if count is None and args.first is None else _realizations(args, count)
    else:
        params, count = build_params(args)
        settings = _settings(args, RUN_DEFAULTS)
        realizations = _realizations(args, count)
    track, wheel = build_structures(args)
    params, wheel = rigid_wheel_mass(args, params, wheel)
    _check_settings(settings, args.batch)
    _refuse_outside_validity(args, params)
    memory = None
    if args.memory_limit is not None:
        memory = _positive_gib(args.memory_limit)
        need = 2 * realization_bytes(params, settings["mode"])  # a batch gets half the limit
        if memory < need:
            raise UsageError(f"--memory-limit {args.memory_limit:g} GiB is too small: one realization of "
                             f"{params.n_points} springs needs {need / 2**30:.3g} GiB (a batch gets half the limit)")
    check_run_fits(params, device, memory, settings["mode"])
    if not args.resume:
        out = output_dir(args, clear=RUN_OUTPUTS + (CHECKPOINT,))
    for name in RUN_OUTPUTS + (CHECKPOINT,):  # the directory is locked: no other writer
        remove_stale_temporaries(out / name)
    result = run_ensemble(params, realizations=realizations, device=device, batch=args.batch,
                          progress=not args.no_progress, checkpoint=out / CHECKPOINT, resume=bool(args.resume),
                          memory_limit=memory, track=track, wheel=wheel, **settings)
    write_outputs(result, out)
    return 0


def _resumed_folder(args) -> Path:
    """The folder of ``--resume DIR``, which a resumed run writes into (``--out`` is refused)."""
    if args.out:
        raise UsageError(f"--out {args.out} with --resume {args.resume}: a resumed run writes into its own "
                         "directory; drop --out")
    return Path(args.resume)


def _run_distributed(args) -> int:
    """``mdroll run --workers N | --scheduler ADDRESS``: the run's units on a Dask cluster; every
    finished unit is kept in OUT/units, from which ``--resume OUT`` continues (the same run:
    options that would change it are refused, naming them)."""
    if build_structures(args) != (None, None):
        raise UsageError("--set track/wheel is not allowed with --workers or --scheduler: the cluster's runs are "
                         "on the rigid track; run on a track without them")
    if args.resume:
        out = _resumed_folder(args)
        (saved,) = saved_specs(out / "units")
        spec = _distributed_spec(args, saved.params.as_dict(), {k: getattr(saved, k) for k in RUN_DEFAULTS},
                                 saved.indices)
        old, new = saved.as_dict(), spec.as_dict()
        changed = [f"{k}: {old['params'][k]!r} -> {v!r}" for k, v in new["params"].items() if old["params"][k] != v]
        changed += [f"{k}: {old[k]!r} -> {v!r}" for k, v in new.items() if k != "params" and old[k] != v]
        if changed:
            raise UsageError(f"--resume {args.resume} continues the run it holds; the command line changes it ("
                             + "; ".join(changed) + "): drop those options or start a new run")
        lock(out, "--resume")
    else:
        spec = _distributed_spec(args, None, RUN_DEFAULTS, None)
        check_output(args)
    with cluster_runner(args) as (runner, device):
        if not args.resume:  # made once the cluster answers: a bad address leaves no folder
            out = output_dir(args, clear=RUN_OUTPUTS)
        runner.checkpoint = (out / "units").absolute()
        try:
            (result,) = runner.run_specs([spec], device=device, progress=not args.no_progress)
        except SchedulerLost as exc:
            where = f"--scheduler {args.scheduler}" if args.scheduler else f"--workers {args.workers}"
            raise UsageError(f"{exc}; continue with: mdroll run --resume {out} {where}") from None
    write_outputs(result, out)
    return 0


def _distributed_spec(args, base_params, base_settings: dict, base_indices) -> EnsembleSpec:
    """The spec of a distributed run: the command line over ``base_params``, ``base_settings``
    and ``base_indices`` (a resumed run's), else over the defaults."""
    params, count = build_params(args, base=base_params)
    settings = _settings(args, base_settings)
    if base_indices is not None and count is None and args.first is None:
        indices = base_indices
    else:
        indices = _realizations(args, count)
    _refuse_outside_validity(args, params)
    return EnsembleSpec(params, first=indices.start, realizations=len(indices), **settings)


def _settings(args, base: dict) -> dict:
    """The run's settings (the keys of :data:`RUN_DEFAULTS`): those given on the command line, else ``base``'s;
    ``--thesis-estimator`` is ``--boundary open --no-window``."""
    if getattr(args, "thesis_estimator", False):
        if args.boundary not in (None, "open"):
            raise UsageError(f"--thesis-estimator with --boundary {args.boundary}: the thesis's record is open")
        args.boundary, args.window = "open", False
    return {k: base[k] if getattr(args, k) is None else getattr(args, k) for k in RUN_DEFAULTS}


def _check_settings(settings: dict, batch) -> None:
    """The run's settings checked as :func:`mdroll.run_ensemble` checks them, before the output
    directory is made: a bad seed, algorithm for the mode or batch leaves no folder behind."""
    check_seed(settings["seed"])
    mode = settings["mode"]
    (algorithm_entry if mode == "decoupled" else coupled_entry)(settings["algorithm"] or default_algorithm(mode))
    if batch is not None:
        check_integer("batch", batch, 1, "realizations")


def _refuse_outside_validity(args, params) -> None:
    """Refuse parameters outside the model's validity (:mod:`mdroll.ensemble.validity`) unless
    ``--force-physics``: the summary's ``physics_warnings`` then say why its numbers are suspect."""
    concerns = parameter_concerns(params)
    if concerns and not args.force_physics:
        raise UsageError("; ".join(concerns) + " (--force-physics runs it anyway)")


def _realizations(args, count: int | None) -> range:
    """The run's realization indices: ``count`` (:data:`~mdroll.params.DEFAULT_REALIZATIONS` when
    None) from ``--first``."""
    count = DEFAULT_REALIZATIONS if count is None else count
    first = args.first or 0
    if not 0 <= first <= MAX_INDEX - max(count, 1) + 1:
        raise UsageError(f"--first {first}: the realization indices must lie in 0 .. {MAX_INDEX} (2^63 - 1)")
    check_count_fits(count)
    return range(first, first + count)


def _positive_gib(value: float) -> int:
    if not (math.isfinite(value) and value > 0):
        raise UsageError(f"--memory-limit {value:g}: must be a positive, finite number of GiB")
    return int(value * 2**30)


def write_outputs(result, out: Path) -> None:
    """spectra.npz, summary.json and the two PNGs, each written atomically (summary.json last:
    its presence marks a complete output), the physics warnings on stderr, and the summary
    table on stdout."""
    result.save(out / "spectra.npz")
    for quantity in ("accel", "force"):
        with atomic_write(out / f"{quantity}_psd.png") as file:
            plotting.plot_psd(result, quantity, file)
    summary = result_summary(result)
    write_band_outputs(result, out, summary)
    summary["physics_warnings"] = result_concerns(result)
    with atomic_write(out / "summary.json", "w") as file:
        json.dump(summary, file, indent=2)

    print(f"\n{result.n_real} realizations x {result.steps} steps, {result.algorithm}, {result.mode}, "
          f"{result.boundary} boundary, device {result.device}\nestimator: {summary['estimator']}")
    rows = [(k, format_value(v["value"]), v["unit"]) for k, v in summary["derived"].items()]
    rows += [("force mean", format_value(result.force_mean), "N"), ("force RMS", format_value(result.force_rms), "N"),
             ("contact lost", str(result.contact_lost_steps), "steps")]
    rows += [(f"unresolved {quantity}", f"{flags['unresolved_bins']}/{flags['of_bins']}", "bins")
             for quantity, flags in summary["resolution"].items()]
    rows += [(f"time {k}", f"{v:.3f}", "s") for k, v in result.timings.items()]
    for name, value, unit in rows:
        print(f"  {name:<20} {value:>14}  {unit}")
    print(f"wrote {out}/: spectra.npz summary.json accel_psd.png force_psd.png bands.csv bands.png")
    for concern in summary["physics_warnings"]:
        print(f"mdroll: warning: {concern}", file=sys.stderr)
