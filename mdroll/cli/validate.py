"""``mdroll validate``: the thesis's analytic formulas checked against ensembles; exit 1 on a failure."""

from __future__ import annotations

import time
from pathlib import Path

from ..ensemble.lines import check_seed
from ..experiments import provenance
from ..validation import CHECKS, SIZES, EnsembleCache, run_checks, select
from ..validation.report import format_table, write_junit, write_report
from .common import (check_file_path, check_output, cluster_options, cluster_runner, device_option, output_dir,
                     output_options, size_options)


def add_parser(sub) -> None:
    p = sub.add_parser("validate", help="check the thesis's analytic formulas against ensembles; exit 1 on a failure")
    size_options(p, quick="small ensembles for a CPU (default)", full="thesis-scale ensembles (GPU)")
    p.add_argument("--only", action="append", metavar="NAME", help="run only this check (repeatable): "
                   + ", ".join(CHECKS))
    p.add_argument("--check", action="append", default=[], metavar="MODULE:FUNCTION",
                   help="also run the checks of this provider (repeatable; docs/validation.md)")
    p.add_argument("--checks", action="append", default=[], metavar="FILE.toml",
                   help="also run the checks of this TOML file (repeatable; schema in docs/validation.md)")
    p.add_argument("--installed", action="store_true",
                   help="also run the checks of installed packages (entry-point group mdroll.checks)")
    p.add_argument("--seed", type=int, default=0)
    device_option(p)
    p.add_argument("--cache-dir", metavar="DIR", help="ensemble cache (default $MDROLL_CACHE_DIR, else "
                   "~/.cache/mdroll/ensembles)")
    p.add_argument("--no-cache", action="store_true", help="neither read nor write the ensemble cache")
    p.add_argument("--junit-xml", metavar="FILE", help="also write a JUnit XML report, one testcase per check")
    cluster_options(p)
    output_options(p)


def execute(args) -> int:
    size = args.size or "quick"
    if args.junit_xml:
        check_file_path(Path(args.junit_xml), "--junit-xml")
    check_seed(args.seed)
    providers = select(args.only or (), args.check, args.checks, args.installed)
    cache = None if args.no_cache else EnsembleCache(args.cache_dir)
    check_output(args)
    began = time.perf_counter()
    with cluster_runner(args) as (runner, device):
        results = run_checks(size, seed=args.seed, device=device, progress=not args.no_progress, providers=providers,
                             runner=runner, cache=cache)
    meta = provenance(device, size, args.seed, SIZES.rung(size))
    out = output_dir(args)  # made once there is a report to write: a failing check leaves no folder
    if cache is not None:
        meta["cache"] = {"dir": str(cache.directory), "hits": cache.hits, "misses": cache.misses}
    write_report(results, out, meta)
    if args.junit_xml:
        write_junit(results, args.junit_xml, seconds=time.perf_counter() - began)
    print(format_table(results))
    print(f"wrote {out}/: validation.json and one PNG per check" + (f"; {args.junit_xml}" if args.junit_xml else ""))
    return 0 if all(r.passed for r in results) else 1
