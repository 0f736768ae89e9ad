"""Command line: ``mdroll params``, ``run``, ``validate``, ``bench`` and ``study`` (also ``python -m mdroll ...``).

Usage errors print one line on stderr, no traceback, and exit with code 2.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import datetime
import fcntl
import json
import math
import os
import secrets
import signal
import sys
import tempfile
from pathlib import Path

from .forces.registry import ALGORITHMS, DEFAULT_ALGORITHMS, REGISTRY
from .params import TEXT_FIELDS, Params

PARAM_NAMES = tuple(f.name for f in dataclasses.fields(Params))
PRESETS = {
    # a small ensemble that finishes in seconds on a laptop CPU
    "quick": {"L": 0.2, "n_real": 8},
}


class UsageError(Exception):
    """Bad command-line input: reported in one line, exit code 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2, no usage dump
        raise UsageError(message)


def _parse_value(key: str, text: str):
    if key not in PARAM_NAMES:
        raise UsageError(f"unknown parameter {key!r}; valid ones are: {', '.join(PARAM_NAMES)}")
    if key in TEXT_FIELDS:
        return text
    try:
        if key == "n_real":
            return int(text)
        return float(text)
    except ValueError as exc:
        raise UsageError(f"--set {key}={text}: not a number ({exc})") from None


def load_config(path: str) -> dict:
    """Parameters from a TOML file: top-level keys, or a ``[params]`` table alone; anything else
    (unknown keys, other tables, top-level keys beside ``[params]``, a ``params`` that is not a
    table) is refused, naming the key."""
    from .files import read_toml

    data = read_toml(path, "config file", UsageError)
    if "params" in data:
        if not isinstance(data["params"], dict):
            raise UsageError(f"config file {path}: 'params' must be a [params] table of parameters, "
                             f"got {data['params']!r}")
        beside = sorted(set(data) - {"params"})
        if beside:
            raise UsageError(f"config file {path}: {beside} beside the [params] table; put every parameter in it")
        data = data["params"]
    tables = sorted(key for key, value in data.items() if isinstance(value, dict))
    if tables:
        raise UsageError(f"config file {path}: unknown table(s) {tables}; only [params] is read")
    unknown = sorted(set(data) - set(PARAM_NAMES))
    if unknown:
        raise UsageError(f"config file {path}: unknown parameter(s) {unknown}; valid ones are: {', '.join(PARAM_NAMES)}")
    return data


def build_params(args, base: dict | None = None) -> Params:
    values: dict = dict(base or {})
    if getattr(args, "preset", None):
        values.update(PRESETS[args.preset])
    if getattr(args, "config", None):
        values.update(load_config(args.config))
    for item in getattr(args, "set", None) or []:
        if "=" not in item:
            raise UsageError(f"--set expects key=value, got {item!r}")
        key, text = item.split("=", 1)
        values[key.strip()] = _parse_value(key.strip(), text.strip())
    if getattr(args, "realizations", None) is not None:
        if args.realizations < 1:
            raise UsageError(f"--realizations {args.realizations}: the number of realizations must be at least 1")
        values["n_real"] = args.realizations
    return Params(**values)


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="mdroll", description="MDR rolling contact on rough rails: ensembles, forces, spectra.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    def common(p):
        p.add_argument("--config", metavar="FILE.toml", help="parameters from a TOML file")
        p.add_argument("--set", action="append", metavar="KEY=VALUE", help="set one parameter (repeatable), SI units")
        p.add_argument("--preset", choices=sorted(PRESETS), help="quick: L = 0.2 m, 8 realizations")

    p_params = sub.add_parser("params", help="print every parameter and derived quantity with units")
    common(p_params)

    p_run = sub.add_parser("run", help="run an ensemble and write spectra, summary and plots")
    common(p_run)
    p_run.add_argument("--realizations", type=int, help="number of realizations (default n_real = 300)")
    p_run.add_argument("--first", type=int, help="index of the first realization (default 0): split an ensemble "
                       "across processes, then `mdroll merge`")
    p_run.add_argument("--seed", type=int, help="master seed (default 0)")
    p_run.add_argument("--algorithm", choices=ALGORITHMS, help="default: " + ", ".join(f"{name} ({mode})" for mode, name in DEFAULT_ALGORITHMS.items()) + "; " + "; ".join(
        f"{entry.name}: {entry.description}, {entry.complexity.text}" for entry in REGISTRY.values()))
    p_run.add_argument("--mode", choices=["decoupled", "coupled"], help="default decoupled")
    p_run.add_argument("--boundary", choices=["open", "periodic"], help="default open")
    p_run.add_argument("--device", default="auto", help="auto, cpu, cuda or cuda:N")
    p_run.add_argument("--batch", type=int, help="realizations per batch (default: from free memory)")
    p_run.add_argument("--memory-limit", type=float, metavar="GIB", help="cap the memory batches are sized from (GiB)")
    p_run.add_argument("--window", action="store_true", default=None, help="Hann window before the FFT")
    p_run.add_argument("--resume", metavar="DIR", help="continue the interrupted run in DIR (its checkpoint.npz); "
                       "its outputs go there too")
    p_run.add_argument("--force-physics", action="store_true", help="run parameters outside the model's validity "
                       "(h0 not small against d0, a time step that shifts the resonance); the summary lists why")
    cluster_options(p_run)
    output(p_run)

    p_val = sub.add_parser("validate", help="check the thesis's analytic formulas against ensembles; exit 1 on a failure")
    size_options(p_val, quick="small ensembles, minutes on a 2-core CPU (default)", full="thesis-scale ensembles (GPU)")
    p_val.add_argument("--only", action="append", metavar="NAME", help="run only this check (repeatable): "
                       + ", ".join(_check_names()))
    p_val.add_argument("--check", action="append", default=[], metavar="MODULE:FUNCTION",
                       help="also run the checks of this provider (repeatable; docs/validation.md)")
    p_val.add_argument("--checks", action="append", default=[], metavar="FILE.toml",
                       help="also run the checks of this TOML file (repeatable; schema in docs/validation.md)")
    p_val.add_argument("--installed", action="store_true",
                       help="also run the checks of installed packages (entry-point group mdroll.checks)")
    p_val.add_argument("--seed", type=int, default=0)
    p_val.add_argument("--device", default="auto", help="auto, cpu, cuda or cuda:N")
    p_val.add_argument("--cache-dir", metavar="DIR", help="ensemble cache (default $MDROLL_CACHE_DIR, else "
                       "~/.cache/mdroll/ensembles)")
    p_val.add_argument("--no-cache", action="store_true", help="neither read nor write the ensemble cache")
    p_val.add_argument("--junit-xml", metavar="FILE", help="also write a JUnit XML report, one testcase per check")
    cluster_options(p_val)
    output(p_val)

    p_merge = sub.add_parser("merge", help="merge the spectra.npz of runs over disjoint realizations into one")
    p_merge.add_argument("inputs", nargs="+", metavar="RUN", help="run directories or spectra.npz files")
    output(p_merge)

    p_inv = sub.add_parser("invert", help="estimate roughness and contact parameters from a spectrum: inverse.json, "
                           "inverse.png and a table")
    p_inv.add_argument("spectrum", nargs="?", metavar="SPECTRUM", help="mdroll spectra.npz (or its run directory), or a "
                       "CSV/NPZ table of frequency and PSD (declare its units)")
    p_inv.add_argument("--known", action="append", metavar="NAME=VALUE", help="a known value in SI units (repeatable): "
                       "v0, m, R, E, nu, E_star, F_N, h0, H, q_min, q_max, a, ...")
    p_inv.add_argument("--free", metavar="NAMES", help="comma-separated parameters to fit (default H,q_min,a,h0 and E_star "
                       "with m known, a_jitter)")
    p_inv.add_argument("--band", metavar="LO:HI[Hz|rad/s]", help="fitted band, e.g. 20:20000Hz (default: the spectrum's, "
                       "above twice the resonance)")
    p_inv.add_argument("--quantity", choices=["accel", "force"], help="which PSD (default accel)")
    p_inv.add_argument("--window", action="store_true", help="the series had the Hann window (mdroll run --window)")
    p_inv.add_argument("--frequency-unit", choices=["Hz", "rad/s"], help="table: unit of the frequency column")
    p_inv.add_argument("--sided", choices=["one", "two"], help="table: one- or two-sided PSD")
    p_inv.add_argument("--density", choices=["Hz", "rad/s"], help="table: PSD per Hz or per rad/s")
    p_inv.add_argument("--passes", type=int, help="number of averaged passes K (default the file's, else 1)")
    p_inv.add_argument("--bin", type=int, default=1, help="average this many neighbouring bins (default 1)")
    p_inv.add_argument("--bootstrap", type=int, default=0, metavar="N", help="parametric bootstrap replicates (mdroll "
                       "spectra only)")
    p_inv.add_argument("--scheduler", metavar="ADDRESS", help="run the bootstrap's ensembles on an existing Dask "
                       "cluster (tcp://host:8786)")
    p_inv.add_argument("--no-profile", action="store_true", help="skip the profile likelihoods")
    p_inv.add_argument("--device", default="auto", help="device of the bootstrap's and round trip's simulations")
    p_inv.add_argument("--round-trip", action="store_true", help="run the round-trip study instead: roundtrip.json, "
                       "roundtrip.png, roundtrip.md")
    size_options(p_inv, quick="round trip: the CPU-sized grid (default)", full="round trip: the full grid (GPU)")
    p_inv.add_argument("--workers", type=int, default=1, help="round trip: processes for the fits (default 1)")
    p_inv.add_argument("--passes-list", metavar="K,K,...", help="round trip: only these numbers of passes")
    p_inv.add_argument("--lengths", metavar="L,L,...", help="round trip: only these rolling distances (m)")
    p_inv.add_argument("--report", nargs="+", metavar="JSON", help="print the Markdown tables of docs/inverse.md "
                       "from round-trip records (roundtrip.json of one or several parts) and stop")
    p_inv.add_argument("--repeats", type=int, metavar="N", help="round trip: seeds per true parameter set (default: "
                       "the grid's, 1 quick, 3 full)")
    p_inv.add_argument("--correction", choices=["simulated", "none"], help="simulated: the closed-form model times "
                       "the ratio that simulations at the estimate measure, iterated (the default for mdroll spectra "
                       "and the round trip: the closed form alone biases H by about -0.008); none: the closed form "
                       "alone (the default for tables)")
    p_inv.add_argument("--correction-passes", type=int, metavar="K", help="passes of each correction ensemble "
                       "(default 32, or more to roll 80 m)")
    p_inv.add_argument("--fill-check", choices=["auto", "on", "off"], default="auto", help="refit with a_jitter held "
                       "at eq 47's h0 R / (2 a) and widen the intervals by the shift (auto, the default: where the noise "
                       "floor and a_jitter are both free, as they trade; on: wherever a_jitter is free)")
    p_inv.add_argument("--discrepancy", metavar="LEVEL,TILT", help="the closed form's unknown discrepancy: log r = 0 "
                       "+- LEVEL +- TILT per octave in the intervals (default 0.03,0.02 for a table fitted without "
                       "the correction, none otherwise; 0: none)")
    p_inv.add_argument("--realistic-only", action="store_true", help="round trip: only the realistic cases (a "
                       "one-sided per-Hz table over 20 Hz - 20 kHz with a noise floor)")
    output(p_inv)

    p_bench = sub.add_parser("bench", help="scaling study of the three algorithms: bench.json, bench.png and a table")
    size_options(p_bench, quick="small sizes, minutes on a 2-core CPU (default)", full="the GPU machine's study")
    p_bench.add_argument("--device", action="append", help="cpu, cuda or cuda:N (repeatable; default every available one)")
    output(p_bench)
    roughness_parser(sub)

    p_study = sub.add_parser("study", help="the thesis's parameter studies (Figures 2-20): figures, JSON and a table "
                             "of claims with verdicts; `study list`, `study all`, `study report DIR`")
    p_study.add_argument("name", help="a study (see `mdroll study list`), 'list', 'all' or 'report'")
    p_study.add_argument("folder", nargs="?", help="report only: the folder of study results to assemble")
    size_options(p_study, quick="small ensembles, under 2 minutes a study on a CPU (default)",
                 full="the thesis's ensembles: 300 realizations (chapters 4-5), 100 per point (chapter 6); GPU")
    p_study.add_argument("--test", dest="size", action="store_const", const="test", help="tiny ensembles (the test suite)")
    p_study.add_argument("--seed", type=int, default=0, help="master seed (default 0)")
    p_study.add_argument("--device", default="auto", help="auto, cpu, cuda or cuda:N")
    p_study.add_argument("--page", help="report only: the Markdown page to write (default <folder>.md)")
    cluster_options(p_study)
    output(p_study)
    return parser


def _check_names() -> list[str]:
    from .validation.checks import CHECKS

    return list(CHECKS)


def size_options(p, quick: str, full: str) -> None:
    """``--quick`` (the default) or ``--full``, into ``args.size``."""
    size = p.add_mutually_exclusive_group()
    size.add_argument("--quick", dest="size", action="store_const", const="quick", help=quick)
    size.add_argument("--full", dest="size", action="store_const", const="full", help=full)


def output(p) -> None:
    p.add_argument("--out", help="output directory (default mdroll-out/<command>-<timestamp>)")
    p.add_argument("--force", action="store_true", help="write into an existing output directory")
    p.add_argument("--no-progress", action="store_true")


#: The lock file a live run holds (fcntl.flock) in its output directory.
LOCK = ".mdroll.lock"
#: What ``run`` and ``merge`` write; ``--force`` removes the old ones first, so that a finished
#: run's files never mix with a new run's.
RUN_OUTPUTS = ("spectra.npz", "summary.json", "accel_psd.png", "force_psd.png", "bands.csv", "bands.png")
_held_locks: list[int] = []


def _output_dir(args, clear: tuple[str, ...] = ()) -> Path:
    """The output directory, checked, created and locked before any work: ``--out`` (an existing
    non-empty one only with ``--force``, which removes the files in ``clear``), or a new
    ``mdroll-out/<command>-<timestamp>-<pid>-<random>``, made by one ``mkdir`` (so two runs
    started in the same second never share it)."""
    if args.out:
        out = Path(args.out)
        _check_directory_path(out, "--out")
        _make_directory(out, "--out", exist_ok=True)
        if any(entry.name != LOCK for entry in out.iterdir()) and not args.force:
            raise UsageError(f"output directory {str(out)!r} exists and is not empty; use --force to write into it")
        _lock(out, "--out")
        for name in clear:
            (out / name).unlink(missing_ok=True)
        return out
    stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
    base = Path("mdroll-out")
    _check_directory_path(base, "output directory")
    _make_directory(base, "output directory", exist_ok=True)
    for _ in range(100):
        out = base / f"{args.command}-{stamp}-{os.getpid()}-{secrets.token_hex(3)}"
        try:
            out.mkdir()
        except FileExistsError:
            continue
        except OSError as exc:
            raise UsageError(f"output directory {str(out)!r}: cannot create it ({exc.strerror})") from None
        _lock(out, "output directory")
        return out
    raise UsageError(f"output directory: no free name under {str(base)!r}")  # pragma: no cover - 2^24 names a pid


def _check_directory_path(path: Path, option: str) -> None:
    """Refuse a path that is a file, or lies under one."""
    for ancestor in (path, *path.parents):
        if ancestor.exists() or ancestor.is_symlink():
            if not ancestor.is_dir():
                where = "is a file" if ancestor == path else f"lies under {str(ancestor)!r}, a file"
                raise UsageError(f"{option} {str(path)!r} {where}, not a directory")
            return


def _make_directory(path: Path, option: str, exist_ok: bool) -> None:
    try:
        path.mkdir(parents=True, exist_ok=exist_ok)
    except OSError as exc:
        raise UsageError(f"{option} {str(path)!r}: cannot create the directory ({exc.strerror})") from None


def _lock(out: Path, option: str) -> None:
    """Hold ``out``'s lock file until the command ends (:func:`main` releases it), and check that
    files can be written there; refuse a directory another live mdroll holds."""
    try:
        fd = os.open(out / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
        tempfile.TemporaryFile(dir=out).close()  # a write probe: permissions, read-only file systems
    except OSError as exc:
        raise UsageError(f"{option} {str(out)!r}: cannot write there ({exc.strerror})") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        owner = os.read(fd, 32).decode(errors="replace").strip() or "?"
        os.close(fd)
        raise UsageError(f"{option} {str(out)!r} is in use by another running mdroll (pid {owner}); wait for it to "
                         "finish or choose another directory") from None
    os.ftruncate(fd, 0)
    os.write(fd, f"{os.getpid()}\n".encode())
    _held_locks.append(fd)


def _release_locks() -> None:
    while _held_locks:
        os.close(_held_locks.pop())


def _fmt(value) -> str:
    return f"{value:.6g}" if isinstance(value, float) else str(value)


def cmd_params(args) -> int:
    p = build_params(args)
    units = {"E": "Pa", "nu": "-", "R": "m", "m": "kg", "F_N": "N", "v0": "m/s", "L": "m", "dx": "m", "h0": "m",
             "H": "-", "q_min": "rad/m", "q_max": "rad/m", "n_real": "-", "q_r": "rad/m"}
    print("parameters")
    for key, value in p.as_dict().items():
        print(f"  {key:<10} {_fmt(value):>14}  {units.get(key, '')}")
    print("derived")
    for key, (value, unit, text) in p.derived().items():
        print(f"  {key:<18} {_fmt(value):>14}  {unit:<9} {text}")
    return 0


RUN_DEFAULTS = {"seed": 0, "algorithm": None, "mode": "decoupled", "boundary": "open", "window": False}


def cmd_run(args) -> int:
    from .devices import resolve_device
    from .ensemble.checkpoint import CHECKPOINT, read_checkpoint
    from .ensemble.batching import check_run_fits, realization_bytes
    from .ensemble.pipeline import run_ensemble

    if args.workers is not None or args.scheduler is not None:
        return _run_distributed(args)
    device = resolve_device(args.device)
    if args.resume:
        if args.out:
            raise UsageError(f"--out {args.out} with --resume {args.resume}: a resumed run writes into its own "
                             "directory; drop --out")
        out = Path(args.resume)
        if not (out / CHECKPOINT).is_file():
            raise UsageError(f"--resume {args.resume}: no {CHECKPOINT} there to continue from")
        _lock(out, "--resume")
        meta, _ = read_checkpoint(out / CHECKPOINT)
        # the checkpoint's run, with anything given on the command line on top (compared when resuming)
        params = build_params(args, base=meta["params"])
        settings = {k: meta[k] if getattr(args, k) is None else getattr(args, k) for k in RUN_DEFAULTS}
        realizations = meta["realizations"] if args.realizations is None and args.first is None else _realizations(args, params)
    else:
        params = build_params(args)
        settings = {k: v if getattr(args, k) is None else getattr(args, k) for k, v in RUN_DEFAULTS.items()}
        realizations = _realizations(args, params)
    _refuse_outside_validity(args, params)
    memory = None
    if args.memory_limit is not None:
        memory = _positive_gib(args.memory_limit)
        need = 2 * realization_bytes(params)  # a batch gets half the limit
        if memory < need:
            raise UsageError(f"--memory-limit {args.memory_limit:g} GiB is too small: one realization of "
                             f"{params.n_points} springs needs {need / 2**30:.3g} GiB (a batch gets half the limit)")
    check_run_fits(params, device, memory)
    if not args.resume:
        out = _output_dir(args, clear=RUN_OUTPUTS + (CHECKPOINT,))
    result = run_ensemble(params, realizations=realizations, device=device, batch=args.batch,
                          progress=not args.no_progress, checkpoint=out / CHECKPOINT, resume=bool(args.resume),
                          memory_limit=memory, **settings)
    write_outputs(result, out)
    return 0


def cluster_options(p) -> None:
    """``--workers N`` and ``--scheduler ADDRESS``: where a command's ensembles run (mdroll.distributed)."""
    p.add_argument("--workers", type=int, metavar="N", help="run on a local Dask cluster of N worker processes "
                   "(one per GPU on a GPU machine, --device cpu for CPU processes)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="run on an existing Dask cluster (tcp://host:8786)")


@contextlib.contextmanager
def cluster_runner(args, checkpoint=None):
    """The runner that ``--workers``/``--scheduler`` ask for (a :class:`mdroll.distributed.DaskRunner`
    for ``run_specs(..., runner=)``), or None to run in this process; and the device the
    ensembles then run on (a local cluster pins one worker to each GPU, which it sees as cuda:0)."""
    if args.workers is None and args.scheduler is None:
        yield None, args.device
        return
    from .distributed import DaskRunner, connect

    device = args.device if args.scheduler is not None or args.device == "cpu" else "auto"
    with connect(args.workers, args.scheduler, args.device) as client:
        yield DaskRunner(client, checkpoint=checkpoint), device


def _run_distributed(args) -> int:
    """``mdroll run --workers N | --scheduler ADDRESS``: the run's units on a Dask cluster; every
    finished unit is kept in OUT/units, from which ``--resume OUT`` continues."""
    from .distributed import saved_specs
    from .ensemble.spec import EnsembleSpec

    if args.resume:
        out = Path(args.resume)
        (spec,) = saved_specs(out / "units")
    else:
        params = build_params(args)
        settings = {k: v if getattr(args, k) is None else getattr(args, k) for k, v in RUN_DEFAULTS.items()}
        indices = _realizations(args, params)
        if not isinstance(indices, range):
            raise UsageError(f"--realizations {args.realizations}: the number of realizations must be at least 1")
        _refuse_outside_validity(args, params)
        spec = EnsembleSpec(params, first=indices.start, realizations=len(indices), **settings)
        out = _output_dir(args, clear=RUN_OUTPUTS)
    with cluster_runner(args, checkpoint=out / "units") as (runner, device):
        (result,) = runner.run_specs([spec], device=device, progress=not args.no_progress)
    write_outputs(result, out)
    return 0


def _refuse_outside_validity(args, params) -> None:
    """Refuse parameters outside the model's validity (:mod:`mdroll.ensemble.validity`) unless
    ``--force-physics``: the summary's ``physics_warnings`` then say why its numbers are suspect."""
    from .ensemble.validity import parameter_concerns

    concerns = parameter_concerns(params)
    if concerns and not args.force_physics:
        raise UsageError("; ".join(concerns) + " (--force-physics runs it anyway)")


def _realizations(args, params):
    from .ensemble.batching import check_count_fits

    count = params.n_real if args.realizations is None else args.realizations
    first = args.first or 0
    if first < 0:
        raise UsageError(f"--first {first}: the first realization index must be >= 0")
    if count > 0:
        check_count_fits(count)
    return range(first, first + count) if count > 0 else count  # count <= 0: run_ensemble names the error


def _positive_gib(value: float) -> int:
    if not (math.isfinite(value) and value > 0):
        raise UsageError(f"--memory-limit {value:g}: must be a positive, finite number of GiB")
    return int(value * 2**30)


def write_outputs(result, out: Path) -> None:
    """spectra.npz, summary.json and the two PNGs, each written atomically (summary.json last:
    its presence marks a complete output), the physics warnings on stderr, and the summary
    table on stdout."""
    from .ensemble.result import result_summary
    from .ensemble.validity import result_concerns
    from .files import atomic_write
    from .plotting import plot_psd
    from .railway.report import write_band_outputs

    result.save(out / "spectra.npz")
    for quantity in ("accel", "force"):
        with atomic_write(out / f"{quantity}_psd.png") as file:
            plot_psd(result, quantity, file)
    summary = result_summary(result)
    write_band_outputs(result, out, summary)
    summary["physics_warnings"] = result_concerns(result)
    with atomic_write(out / "summary.json", "w") as file:
        json.dump(summary, file, indent=2)

    print(f"\n{result.n_real} realizations x {result.steps} steps, {result.algorithm}, {result.mode}, "
          f"{result.boundary} boundary, device {result.device}")
    rows = [(k, _fmt(v["value"]), v["unit"]) for k, v in summary["derived"].items()]
    rows += [("force mean", _fmt(result.force_mean), "N"), ("force RMS", _fmt(result.force_rms), "N"),
             ("contact lost", str(result.contact_lost_steps), "steps")]
    rows += [(f"time {k}", f"{v:.3f}", "s") for k, v in result.timings.items()]
    for name, value, unit in rows:
        print(f"  {name:<20} {value:>14}  {unit}")
    print(f"wrote {out}/: spectra.npz summary.json accel_psd.png force_psd.png bands.csv bands.png")
    for concern in summary["physics_warnings"]:
        print(f"mdroll: warning: {concern}", file=sys.stderr)


def cmd_merge(args) -> int:
    from .ensemble.result import EnsembleResult

    paths = [Path(p) / "spectra.npz" if Path(p).is_dir() else Path(p) for p in args.inputs]
    missing = [str(p) for p in paths if not p.is_file()]
    if missing:
        raise UsageError(f"no spectra.npz at {', '.join(missing)}")
    if args.out:
        _check_directory_path(Path(args.out), "--out")
    result = EnsembleResult.merge([EnsembleResult.load(p) for p in paths])
    write_outputs(result, _output_dir(args, clear=RUN_OUTPUTS))
    return 0


def cmd_validate(args) -> int:
    import time

    from .experiments import provenance
    from .validation import EnsembleCache, SIZES, run_checks, select
    from .validation.report import format_table, write_junit, write_report

    size = args.size or "quick"
    if args.junit_xml:
        _check_file_path(Path(args.junit_xml), "--junit-xml")
    providers = select(args.only or (), args.check, args.checks, args.installed)
    cache = None if args.no_cache else EnsembleCache(args.cache_dir)
    out = _output_dir(args)
    began = time.perf_counter()
    with cluster_runner(args) as (runner, device):
        results = run_checks(size, seed=args.seed, device=device, progress=not args.no_progress, providers=providers,
                             runner=runner, cache=cache)
    meta = provenance(device, size, args.seed, SIZES.rung(size))
    if cache is not None:
        meta["cache"] = {"dir": str(cache.directory), "hits": cache.hits, "misses": cache.misses}
    write_report(results, out, meta)
    if args.junit_xml:
        write_junit(results, args.junit_xml, seconds=time.perf_counter() - began)
    print(format_table(results))
    print(f"wrote {out}/: validation.json and one PNG per check" + (f"; {args.junit_xml}" if args.junit_xml else ""))
    return 0 if all(r.passed for r in results) else 1


def _check_file_path(path: Path, option: str) -> None:
    """A file to be written later: its folder must exist and be a writable directory."""
    folder = path.parent
    if path.is_dir():
        raise UsageError(f"{option} {path}: is a directory, expected a file name")
    if not folder.is_dir() or not os.access(folder, os.W_OK):
        raise UsageError(f"{option} {path}: the folder {folder} does not exist or is not writable")


def cmd_bench(args) -> int:
    from .bench import format_table, plot_study, run_study
    from .experiments import write_json

    out = _output_dir(args)
    say = (lambda text: None) if args.no_progress else (lambda text: print(text, file=sys.stderr, flush=True))
    record = run_study(args.size or "quick", devices=args.device, progress=say)
    write_json(out / "bench.json", record, indent=2)
    plot_study(record, out / "bench.png")
    print(format_table(record))
    print(f"wrote {out}/: bench.json bench.png")
    return 0


def roughness_parser(sub) -> None:
    """``mdroll roughness check | filter | profile``."""
    p = sub.add_parser("roughness", help="roughness models: physics checks, contact filter vs CNOSSOS-EU, measured "
                       "profiles (docs/roughness.md)")
    tasks = p.add_subparsers(dest="task", required=True, parser_class=_Parser)
    check = tasks.add_parser("check", help="line spectra, dB round trip, measured profile, eq 39 high band, eq 63, "
                             "coupled vs decoupled, contact filter: roughness.json; exit 1 on a failure")
    size_options(check, quick="CPU sizes, about a minute (default)", full="thesis-scale ensembles (GPU)")
    check.add_argument("--only", action="append", metavar="NAME", help="run only this study (repeatable): "
                       "lines, round_trip, measured_profile, high_band, eq63, dynamics, contact_filter")
    check.add_argument("--seed", type=int, default=0)
    check.add_argument("--device", default="auto", help="auto, cpu, cuda or cuda:N")
    output(check)
    filt = tasks.add_parser("filter", help="the MDR contact filter beside CNOSSOS-EU A3: contact_filter.csv and .png")
    output(filt)
    prof = tasks.add_parser("profile", help="a measured profile (CSV/NPY: x, h in m; or h with --dx): Welch PSD with "
                            "its confidence band (profile_psd.csv, usable as roughness_table) and its band levels")
    prof.add_argument("file")
    prof.add_argument("--dx", type=float, help="sample spacing (m) of a one-column profile")
    prof.add_argument("--segment", type=float, help="Welch segment length (m; default an eighth of the profile)")
    output(prof)


def cmd_roughness(args) -> int:
    from .railway import tasks as cli_tasks

    if args.task == "check":
        from .devices import resolve_device
        from .railway.studies import RAILWAY_STUDIES

        unknown = RAILWAY_STUDIES.unknown(args.only or ())
        if unknown:
            raise UsageError(f"--only: unknown study(ies) {unknown}; valid ones are: {', '.join(RAILWAY_STUDIES)}")
        device = resolve_device(args.device)
        passed = cli_tasks.check(args.size or "quick", args.seed, device, _output_dir(args), args.only)
        return 0 if passed else 1
    if args.task == "filter":
        cli_tasks.contact_filter(_output_dir(args))
        return 0
    cli_tasks.profile(args.file, args.dx, args.segment, _output_dir(args))
    return 0


def cmd_study(args) -> int:
    from .studies import STUDIES, check_name, run_study
    from .studies.report import format_table, write_page, write_study

    if args.name == "list":
        for study in STUDIES.values():
            print(f"{study.name:<16} {study.figures:<10} {study.equations:<22} {study.title}")
        return 0
    if args.name == "report":
        if not args.folder:
            raise UsageError("study report needs the folder of study results, e.g. `mdroll study report docs/studies`")
        if not Path(args.folder).is_dir():
            raise UsageError(f"study report: {args.folder!r} is not a folder")
        try:
            print(f"wrote {write_page(args.folder, args.page)}")
        except FileNotFoundError as exc:
            raise UsageError(str(exc)) from None
        return 0
    if args.folder:
        raise UsageError(f"unexpected argument {args.folder!r}: only `study report` takes a folder")
    names = list(STUDIES) if args.name == "all" else [check_name(args.name).name]
    out = _output_dir(args)
    with cluster_runner(args) as (runner, device):
        for name in names:
            run = run_study(name, args.size or "quick", device=device, seed=args.seed, progress=not args.no_progress,
                            cluster=runner)
            paths = write_study(run, out)
            print(format_table(run.record))
            print(f"wrote {paths[0].parent}/: " + " ".join(p.name for p in paths) + "\n", flush=True)
    return 0


def _band(text: str):
    """``LO:HI`` with an optional unit suffix Hz or rad/s (default rad/s) -> (lo, hi) in rad/s."""
    import math

    unit = 1.0
    for suffix, factor in (("rad/s", 1.0), ("Hz", 2.0 * math.pi)):
        if text.endswith(suffix):
            text, unit = text[: -len(suffix)], factor
            break
    try:
        lo, hi = (float(v) * unit for v in text.split(":"))
    except ValueError:
        raise UsageError(f"--band {text!r}: expected LO:HI with an optional unit Hz or rad/s, e.g. 20:20000Hz") from None
    return lo, hi


def _numbers(text, kind, option):
    """A comma-separated list of numbers (None for None)."""
    if text is None:
        return None
    try:
        values = [kind(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise UsageError(f"{option} {text!r}: expected comma-separated numbers") from None
    if not values or any(v <= 0 for v in values):
        raise UsageError(f"{option} {text!r}: expected positive numbers")
    return values


def _discrepancy(text):
    """``--discrepancy``: ``LEVEL,TILT`` or ``0`` (fit checks the values; None for the default)."""
    if text is None:
        return None
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise UsageError(f"--discrepancy {text!r}: expected LEVEL,TILT (e.g. 0.03,0.02) or 0") from None
    return 0 if values == [0.0] else tuple(values)


def _known(items) -> dict:
    known = {}
    for item in items or []:
        if "=" not in item:
            raise UsageError(f"--known expects NAME=VALUE, got {item!r}")
        key, text = item.split("=", 1)
        try:
            known[key.strip()] = float(text)
        except ValueError:
            raise UsageError(f"--known {item}: {text!r} is not a number") from None
    return known


#: What ``invert`` writes (``--force`` removes the old ones first).
INVERT_OUTPUTS = ("inverse.json", "inverse.png", "roundtrip.json", "roundtrip.png", "roundtrip.md")


def cmd_invert(args) -> int:
    from .devices import resolve_device
    from .files import atomic_write
    from .inverse import fit, read_spectrum

    if args.report:
        from .inverse.roundtrip_report import merge_records, report

        records = []
        for name in args.report:
            try:
                records.append(json.loads(Path(name).read_text()))
            except (OSError, ValueError) as error:
                raise UsageError(f"--report {name}: not a readable round-trip record ({error})") from None
        print(report(merge_records(records)))
        return 0
    if args.round_trip:
        from .experiments import write_json
        from .inverse.roundtrip import run_study
        from .inverse.roundtrip_report import format_table, plot_study

        if args.spectrum:
            raise UsageError("--round-trip simulates its own spectra: give no SPECTRUM")
        if args.workers < 1:
            raise UsageError(f"--workers {args.workers}: must be at least 1")
        out = _output_dir(args, clear=INVERT_OUTPUTS)
        say = (lambda text: None) if args.no_progress else (lambda text: print(text, file=sys.stderr, flush=True))
        record = run_study(args.size or "quick", device=resolve_device(args.device), folder=out, progress=say,
                           workers=args.workers, passes=_numbers(args.passes_list, int, "--passes-list"),
                           lengths=_numbers(args.lengths, float, "--lengths"), correction=args.correction or "simulated",
                           repeats=args.repeats, correction_passes=args.correction_passes,
                           realistic_only=args.realistic_only)
        written = ["roundtrip.json", "roundtrip.md"]
        if record["rows"]:  # not for the realistic cases alone
            with atomic_write(out / "roundtrip.png") as file:
                plot_study(record, file)
            written.insert(1, "roundtrip.png")
        with atomic_write(out / "roundtrip.md", "w") as file:
            file.write(format_table(record) + "\n")
        write_json(out / "roundtrip.json", record)
        print(format_table(record))
        print(f"{record['seconds']:.0f} s; wrote {out}/: {' '.join(written)}")
        return 0
    if not args.spectrum:
        raise UsageError("give a SPECTRUM file (or --round-trip)")
    path = Path(args.spectrum)
    if path.is_dir():
        path = path / "spectra.npz"
    spectrum = read_spectrum(path, quantity=args.quantity, window=args.window, frequency_unit=args.frequency_unit,
                             sided=args.sided, density=args.density, passes=args.passes)
    free = [n.strip() for n in args.free.split(",") if n.strip()] if args.free else None
    result = fit(spectrum, known=_known(args.known), free=free, band=_band(args.band) if args.band else None,
                 passes=args.passes, bin=args.bin, profile=not args.no_profile, correction=args.correction,
                 correction_passes=args.correction_passes, device=resolve_device(args.device), fill_check=args.fill_check,
                 discrepancy=_discrepancy(args.discrepancy))
    if args.bootstrap:
        from .inverse.roundtrip import bootstrap

        # the replicates' ensembles on an existing Dask cluster with --scheduler (--workers is the
        # round trip's fit processes here)
        cluster = argparse.Namespace(workers=None, scheduler=args.scheduler, device=args.device)
        with cluster_runner(cluster) as (runner, device):
            result.bootstrap = bootstrap(spectrum, result, args.bootstrap, device=resolve_device(device)
                                         if runner is None else device, bin=args.bin, runner=runner)
    out = _output_dir(args, clear=INVERT_OUTPUTS)
    from .inverse.plot import plot_fit

    with atomic_write(out / "inverse.png") as file:
        plot_fit(result, file)
    with atomic_write(out / "inverse.json", "w") as file:
        json.dump({"source": str(path), **result.to_dict()}, file, indent=1)
    print(result.table())
    if result.bootstrap:
        b = result.bootstrap
        print(f"bootstrap ({b['replicates']} replicates): percentile 95%, bias, bias-corrected estimate, basic 95%")
        for name, (lo, hi) in b["ci95"].items():
            low, high = b["ci95_basic"][name]
            print(f"  {name:<9} {lo:.6g} .. {hi:.6g}  {b['bias'][name]:+.4g}  {b['bias_corrected'][name]:.6g}  "
                  f"{low:.6g} .. {high:.6g}")
    print(f"wrote {out}/: inverse.json inverse.png")
    return 0


class _Terminated(KeyboardInterrupt):
    """SIGTERM (a scheduler stopping the job), raised so that it unwinds like Ctrl-C: temporary
    files are removed, the lock released, the last checkpoint kept."""


def _raise_terminated(signum, frame):
    raise _Terminated


def main(argv=None) -> int:
    previous = None
    with contextlib.suppress(ValueError):  # only the main thread may set a handler
        previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        args = _parser().parse_args(argv)
        code = {"params": cmd_params, "run": cmd_run, "validate": cmd_validate, "bench": cmd_bench,
                "merge": cmd_merge, "roughness": cmd_roughness, "study": cmd_study,
                "invert": cmd_invert}[args.command](args)
        sys.stdout.flush()  # here, so that a closed pipe is met inside the handlers below
        return code
    except UsageError as exc:
        print(f"mdroll: error: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:  # ParameterError, DeviceError: bad values, named in the message
        print(f"mdroll: error: {exc}", file=sys.stderr)
        return 2
    except FloatingPointError as exc:  # NonFiniteError: a force or spectrum not finite, realization and stage named
        print(f"mdroll: error: {exc}; the parameters give non-finite numbers", file=sys.stderr)
        return 2
    except MemoryError:
        print("mdroll: error: out of memory; lower --batch or --memory-limit, or L (more than the free memory was "
              "taken while the run went on)", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader left (mdroll params | head -2): nothing more to say
        with contextlib.suppress(OSError, ValueError, AttributeError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141  # 128 + SIGPIPE, as a tool killed by the closed pipe reports
    except _Terminated:
        print("mdroll: terminated; continue with mdroll run --resume DIR", file=sys.stderr)
        return 143  # 128 + SIGTERM
    except KeyboardInterrupt:
        print("mdroll: interrupted", file=sys.stderr)
        return 130
    finally:
        _release_locks()
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
