"""``mdroll invert``: roughness and contact parameters estimated from a spectrum (inverse.json,
inverse.png and a table), the round-trip study, and its report."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import math
import sys
from pathlib import Path

from ..arguments import check_integer
from ..devices import resolve_device
from ..errors import ParameterError, UsageError
from ..experiments import read_record, write_json
from ..files import atomic_write
from ..track import Track
from ..wheel import Wheel
from .common import (build_structures, check_output, cluster_runner, device_option, output_dir, output_options,
                     progress_printer, reading, size_options)

#: Spectra of more bins than this get a progress line before the fit (the readers bound them).
LARGE_SPECTRUM = 50_000
#: What ``invert`` writes (``--force`` removes the old ones first).
#: The exit code of a fit the acceptance gate rejects (:mod:`mdroll.inverse.acceptance`).
REJECTED = 3
INVERT_OUTPUTS = ("inverse.json", "inverse.png", "roundtrip.json", "roundtrip.png", "roundtrip.md")


def add_parser(sub) -> None:
    p = sub.add_parser("invert", help="estimate roughness and contact parameters from a spectrum: inverse.json, "
                       "inverse.png and a table")
    p.add_argument("spectrum", nargs="?", metavar="SPECTRUM", help="mdroll spectra.npz (or its run directory), or a "
                   "CSV/NPZ table of frequency and PSD (declare its units)")
    p.add_argument("--known", action="append", metavar="NAME=VALUE", help="a known value in SI units (repeatable): "
                   "v0, m, R, E, nu, E_star, F_N, h0, H, q_min, q_max, a, ...")
    p.add_argument("--set", action="append", metavar="track=PRESET|track.KEY=VALUE|wheel=...", help="the known "
                   "track and wheel under the contact of a measured table (repeatable; docs/track.md): the model is "
                   "then the linear chain; a coupled mdroll run on a track records its own")
    p.add_argument("--free", metavar="NAMES", help="comma-separated parameters to fit (default H,q_min,a,h0 and E_star "
                   "with m known, a_jitter)")
    p.add_argument("--band", metavar="LO:HI[Hz|rad/s]", help="fitted band, e.g. 20:20000Hz (default: the spectrum's, "
                   "above twice the resonance)")
    p.add_argument("--quantity", choices=["accel", "force"], help="which PSD (default accel)")
    p.add_argument("--window", action="store_true", default=None, help="a table's series had the Hann window (an "
                   "mdroll spectra.npz records its own)")
    p.add_argument("--frequency-unit", choices=["Hz", "rad/s"], help="table: unit of the frequency column")
    p.add_argument("--sided", choices=["one", "two"], help="table: one- or two-sided PSD")
    p.add_argument("--density", choices=["Hz", "rad/s"], help="table: PSD per Hz or per rad/s")
    p.add_argument("--passes", type=int, help="number of averaged passes K (default the file's, else 1)")
    p.add_argument("--bin", type=int, default=1, help="average this many neighbouring bins (default 1)")
    p.add_argument("--bootstrap", type=int, default=0, metavar="N", help="parametric bootstrap replicates (mdroll "
                   "spectra only)")
    p.add_argument("--scheduler", metavar="ADDRESS", help="run the bootstrap's ensembles on an existing Dask "
                   "cluster (tcp://host:8786)")
    p.add_argument("--no-profile", action="store_true", help="skip the profile likelihoods")
    device_option(p, "device of the bootstrap's and round trip's simulations")
    p.add_argument("--round-trip", action="store_true", help="run the round-trip study instead: roundtrip.json, "
                   "roundtrip.png, roundtrip.md")
    size_options(p, quick="round trip: the CPU-sized grid (default)", full="round trip: the full grid (GPU)")
    p.add_argument("--workers", type=int, help="round trip: processes for the fits (default 1, at most the cores)")
    p.add_argument("--passes-list", metavar="K,K,...", help="round trip: only these numbers of passes")
    p.add_argument("--lengths", metavar="L,L,...", help="round trip: only these rolling distances (m)")
    p.add_argument("--report", nargs="+", metavar="JSON", help="print the Markdown tables of docs/inverse.md "
                   "from round-trip records (roundtrip.json of one or several parts) and stop")
    p.add_argument("--repeats", type=int, metavar="N", help="round trip: seeds per true parameter set (default: "
                   "the grid's, 1 quick, 3 full)")
    p.add_argument("--correction", choices=["simulated", "none"], help="simulated: the closed-form model times "
                   "the ratio that simulations at the estimate measure, iterated (the default for mdroll spectra "
                   "and the round trip, as the closed form alone biases H: docs/inverse.md); none: the closed form "
                   "alone (the default for tables)")
    p.add_argument("--correction-passes", type=int, metavar="K", help="passes of each correction ensemble "
                   "(default 32, or more to roll 80 m)")
    p.add_argument("--fill-check", choices=["auto", "on", "off"], default="auto", help="refit with a_jitter held "
                   "at eq 47's h0 R / (2 a) and widen the intervals by the shift (auto, the default: where the noise "
                   "floor and a_jitter are both free, as they trade; on: wherever a_jitter is free)")
    p.add_argument("--discrepancy", metavar="LEVEL,TILT", help="the closed form's unknown discrepancy: log r = 0 "
                   "+- LEVEL +- TILT per octave in the intervals (default 0.03,0.02 for a table fitted without "
                   "the correction, none otherwise; 0: none)")
    p.add_argument("--realistic-only", action="store_true", help="round trip: only the realistic cases (a "
                   "one-sided per-Hz table over 20 Hz - 20 kHz with a noise floor)")
    output_options(p)


def execute(args) -> int:
    if args.report:
        return _report(args)
    if args.round_trip:
        return _round_trip(args)
    if not args.spectrum:
        raise UsageError("give a SPECTRUM file (or --round-trip)")
    return _fit(args)


# imported inside the functions below, when the command runs, for start-up cost: mdroll.inverse
# loads scipy.stats


def _report(args) -> int:
    """``--report JSON ...``: the Markdown tables of round-trip records."""
    from ..inverse.roundtrip_report import ROUNDTRIP_RECORD, merge_records, report

    with _option("--report"):
        records = [read_record(name, ROUNDTRIP_RECORD) for name in args.report]
    print(report(merge_records(records)))
    return 0


def _round_trip(args) -> int:
    """``--round-trip``: spectra simulated at known parameters, fitted, and the estimates compared."""
    from ..inverse.roundtrip import check_study_counts, run_study
    from ..inverse.roundtrip_report import format_table, plot_study

    if args.spectrum:
        raise UsageError("--round-trip simulates its own spectra: give no SPECTRUM")
    fitting = [option for option, value in (("--known", args.known), ("--free", args.free), ("--band", args.band),
                                            ("--quantity", args.quantity), ("--window", args.window),
                                            ("--frequency-unit", args.frequency_unit), ("--sided", args.sided),
                                            ("--density", args.density), ("--passes", args.passes),
                                            ("--bootstrap", args.bootstrap or None), ("--scheduler", args.scheduler),
                                            ("--discrepancy", args.discrepancy)) if value is not None]
    if fitting:
        raise UsageError(f"{', '.join(fitting)}: for fitting a SPECTRUM, not for --round-trip (which sets its own)")
    passes = _numbers(args.passes_list, int, "--passes-list")
    lengths = _numbers(args.lengths, float, "--lengths")
    workers = 1 if args.workers is None else args.workers
    for option, keyword, value in (("--workers", "workers", workers), ("--passes-list", "passes", passes),
                                   ("--correction-passes", "correction_passes", args.correction_passes),
                                   ("--repeats", "repeats", args.repeats), ("--lengths", "lengths", lengths)):
        with _option(option):
            check_study_counts(**{keyword: value})
    device = resolve_device(args.device)  # every option checked before the folder is made
    out = output_dir(args, clear=INVERT_OUTPUTS)
    record = run_study(args.size or "quick", device=device, folder=out, progress=progress_printer(args),
                       workers=workers, passes=passes, lengths=lengths, correction=args.correction or "simulated",
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


def _fit(args) -> int:
    """SPECTRUM: the fit, its plot and table, and the bootstrap's intervals with ``--bootstrap N``."""
    from ..inverse import fit, read_spectrum
    from ..inverse.observed import MAX_PASSES
    from ..inverse.plot import plot_fit
    from ..inverse.roundtrip import bootstrap, check_replicates

    path = Path(args.spectrum)
    if path.is_dir():
        path = path / "spectra.npz"
    alone = [option for option, value in (("--workers", args.workers), ("--passes-list", args.passes_list),
                                          ("--lengths", args.lengths), ("--repeats", args.repeats),
                                          ("--realistic-only", args.realistic_only or None)) if value is not None]
    if alone:
        raise UsageError(f"{', '.join(alone)}: for --round-trip only, not for fitting a SPECTRUM")
    if args.bootstrap:
        with _option("--bootstrap"):
            check_replicates(args.bootstrap)
    elif args.scheduler:
        raise UsageError("--scheduler runs the bootstrap's ensembles: give --bootstrap N with it")
    for option, value, maximum in (("--passes", args.passes, MAX_PASSES), ("--bin", args.bin, None),
                                   ("--correction-passes", args.correction_passes, MAX_PASSES)):
        if value is not None:
            with _option(option):
                check_integer(option.lstrip("-").replace("-", "_"), value, 1, maximum=maximum)
    device = resolve_device(args.device)
    check_output(args)
    with reading("spectrum file", path):
        spectrum = read_spectrum(path, quantity=args.quantity, window=args.window, frequency_unit=args.frequency_unit,
                                 sided=args.sided, density=args.density, passes=args.passes)
    spectrum = _with_track(args, spectrum, path)
    simulated = (args.correction or ("simulated" if spectrum.simulation else "none")) == "simulated"
    if args.correction_passes is not None and not simulated:
        raise UsageError(f"--correction-passes {args.correction_passes}: {path} is fitted without the simulated "
                         "correction (a table's default, or --correction none), which alone runs those ensembles")
    if args.bootstrap and not spectrum.simulation:
        raise UsageError(f"--bootstrap: {path} is a table; the bootstrap simulates at the estimate with the "
                         "simulation's L and dx, which only an mdroll spectra.npz holds")
    if spectrum.omega.size > LARGE_SPECTRUM:
        progress_printer(args)(f"{path}: {spectrum.omega.size} bins; the fit's time grows with them (--bin K "
                               "averages K neighbouring bins first)")
    free = [n.strip() for n in args.free.split(",") if n.strip()] if args.free else None
    result = fit(spectrum, known=_known(args.known), free=free, band=_band(args.band) if args.band else None,
                 passes=args.passes, bin=args.bin, profile=not args.no_profile, correction=args.correction,
                 correction_passes=args.correction_passes, device=device, fill_check=args.fill_check,
                 discrepancy=_discrepancy(args.discrepancy))
    if args.bootstrap:
        # the replicates' ensembles on an existing Dask cluster with --scheduler (--workers is the
        # round trip's fit processes here)
        cluster = argparse.Namespace(workers=None, scheduler=args.scheduler, device=args.device)
        with cluster_runner(cluster) as (runner, device):
            result.bootstrap = bootstrap(spectrum, result, args.bootstrap, device=resolve_device(device)
                                         if runner is None else device, bin=args.bin, runner=runner)
    out = output_dir(args, clear=INVERT_OUTPUTS)
    with atomic_write(out / "inverse.png") as file:
        plot_fit(result, file)
    with atomic_write(out / "inverse.json", "w") as file:
        track = {"known_track": spectrum.known_track.describe()} if spectrum.known_track is not None else {}
        json.dump({"source": str(path), **track, **result.to_dict()}, file, indent=1)
    print(result.table())
    if not result.success:
        print(f"mdroll: warning: the optimizer stopped without converging ({result.message}); the estimates and "
              "intervals may not be the likelihood's maximum", file=sys.stderr)
    if result.bootstrap:
        b = result.bootstrap
        print(f"bootstrap ({b['replicates']} replicates): percentile 95%, bias, bias-corrected estimate, basic 95%")
        for name, (lo, hi) in b["ci95"].items():
            low, high = b["ci95_basic"][name]
            print(f"  {name:<9} {lo:.6g} .. {hi:.6g}  {b['bias'][name]:+.4g}  {b['bias_corrected'][name]:.6g}  "
                  f"{low:.6g} .. {high:.6g}")
    print(f"wrote {out}/: inverse.json inverse.png")
    if not result.accepted:
        print(f"mdroll: the fit is rejected: {result.rejection}; its estimates are not the spectrum's parameters "
              "(inverse.json: \"accepted\": false)", file=sys.stderr)
        return REJECTED
    return 0


def _with_track(args, spectrum, path):
    """The spectrum with the track and wheel of ``--set`` (a table's), refused for a run that records
    its own and with ``--bootstrap`` (its ensembles roll on the rigid rail)."""
    from ..inverse.track_model import KnownTrack

    if spectrum.known_track is not None and args.bootstrap:
        raise UsageError(f"--bootstrap with {path}, a run on a track: the bootstrap's ensembles roll on the rigid rail")
    if not args.set:
        return spectrum
    bad = [item for item in args.set if item.split("=", 1)[0].split(".", 1)[0].strip() not in ("track", "wheel")]
    if bad:
        raise UsageError(f"--set {bad[0]}: invert takes only the track's and the wheel's settings (track=PRESET, "
                         "track.KEY=VALUE, wheel=PRESET, wheel.KEY=VALUE)")
    if spectrum.known_track is not None:
        raise UsageError(f"--set with {path}: the run records its own track and wheel; drop --set")
    if args.bootstrap:
        raise UsageError("--bootstrap with --set track/wheel: the bootstrap's ensembles roll on the rigid rail")
    track, wheel = build_structures(args)
    return dataclasses.replace(spectrum, known_track=KnownTrack(track or Track.preset("rigid"),
                                                                wheel or Wheel.preset("rigid")))


@contextlib.contextmanager
def _option(name: str):
    """A ParameterError of a value checked for the option ``name``, as one line naming the option."""
    try:
        yield
    except ParameterError as exc:
        raise UsageError(f"{name}: {exc}") from None


def _band(text: str):
    """``LO:HI`` with an optional unit suffix Hz or rad/s (default rad/s) -> (lo, hi) in rad/s."""
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
