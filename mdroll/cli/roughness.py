"""``mdroll roughness check | filter | profile``: the roughness models' physics checks, the contact
filter beside CNOSSOS-EU, and measured profiles (docs/roughness.md)."""

from __future__ import annotations

from ..devices import resolve_device
from ..ensemble.lines import check_seed
from ..errors import UsageError
from .common import Parser, check_output, device_option, output_dir, output_options, size_options


def add_parser(sub) -> None:
    p = sub.add_parser("roughness", help="roughness models: physics checks, contact filter vs CNOSSOS-EU, measured "
                       "profiles (docs/roughness.md)")
    tasks = p.add_subparsers(dest="task", required=True, parser_class=Parser)
    check = tasks.add_parser("check", help="line spectra, dB round trip, measured profile, eq 39 high band, eq 63, "
                             "coupled vs decoupled, contact filter, the wheel on a track at small and large "
                             "roughness: roughness.json; exit 1 on a failure")
    size_options(check, quick="sizes for a CPU (default)", full="thesis-scale ensembles (GPU)")
    check.add_argument("--only", action="append", metavar="NAME", help="run only this study (repeatable): "
                       "lines, round_trip, measured_profile, high_band, eq63, dynamics, contact_filter, track")
    check.add_argument("--seed", type=int, default=0)
    device_option(check)
    output_options(check)
    filt = tasks.add_parser("filter", help="the MDR contact filter beside CNOSSOS-EU A3: contact_filter.csv and .png")
    output_options(filt)
    prof = tasks.add_parser("profile", help="a measured profile (CSV/NPY: x, h in m; or h with --dx): Welch PSD with "
                            "its confidence band (profile_psd.csv, usable as roughness_table) and its band levels")
    prof.add_argument("file")
    prof.add_argument("--dx", type=float, help="sample spacing (m) of a one-column profile")
    prof.add_argument("--segment", type=float, help="Welch segment length (m; default an eighth of the profile)")
    output_options(prof)


def execute(args) -> int:
    # imported when the command runs, for start-up cost: the railway tasks load scipy.stats
    from ..railway import tasks
    from ..railway.studies import RAILWAY_STUDIES

    if args.task == "check":
        unknown = RAILWAY_STUDIES.unknown(args.only or ())
        if unknown:
            raise UsageError(f"--only: unknown study(ies) {unknown}; valid ones are: {', '.join(RAILWAY_STUDIES)}")
        check_seed(args.seed)
        device = resolve_device(args.device)
        passed = tasks.check(args.size or "quick", args.seed, device, output_dir(args), args.only)
        return 0 if passed else 1
    if args.task == "filter":
        tasks.contact_filter(output_dir(args))
        return 0
    check_output(args)
    tasks.profile(args.file, args.dx, args.segment, lambda: output_dir(args))
    return 0
