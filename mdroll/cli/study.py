"""``mdroll study``: the thesis's parameter studies: figures, JSON and a table of claims with verdicts."""

from __future__ import annotations

from pathlib import Path

from ..devices import resolve_device
from ..ensemble.lines import check_seed
from ..errors import UsageError
from ..studies import STUDIES, check_name, run_study
from ..studies.report import format_table, write_page, write_study
from .common import (check_file_path, check_output, cluster_options, cluster_runner, device_option, output_dir,
                     output_options, size_options)


def add_parser(sub) -> None:
    p = sub.add_parser("study", help="the thesis's parameter studies (Figures 2-20): figures, JSON and a table "
                       "of claims with verdicts; `study list`, `study all`, `study report DIR`")
    p.add_argument("name", help="a study (see `mdroll study list`), 'list', 'all' or 'report'")
    p.add_argument("folder", nargs="?", help="report only: the folder of study results to assemble")
    size_options(p, quick="small ensembles for a CPU (default)",
                 full="the thesis's ensembles: 300 realizations (chapters 4-5), 100 per point (chapter 6); GPU")
    p.add_argument("--test", dest="size", action="store_const", const="test", help="tiny ensembles (the test suite)")
    p.add_argument("--seed", type=int, default=0, help="master seed (default 0)")
    device_option(p)
    p.add_argument("--page", help="report only: the Markdown page to write (default <folder>.md)")
    cluster_options(p)
    output_options(p)


def execute(args) -> int:
    if args.folder and args.name != "report":
        raise UsageError(f"unexpected argument {args.folder!r}: only `study report` takes a folder")
    if args.name == "list":
        for study in STUDIES.values():
            print(f"{study.name:<16} {study.figures:<10} {study.equations:<22} {study.title}")
        return 0
    if args.name == "report":
        return _report(args)
    names = list(STUDIES) if args.name == "all" else [check_name(args.name).name]
    check_seed(args.seed)
    if args.workers is None and args.scheduler is None:
        resolve_device(args.device)  # here, before the folder is made
    check_output(args)
    with cluster_runner(args) as (runner, device):
        out = output_dir(args)  # once the cluster answers: a bad address leaves no folder
        for name in names:
            run = run_study(name, args.size or "quick", device=device, seed=args.seed, progress=not args.no_progress,
                            cluster=runner)
            paths = write_study(run, out)
            print(format_table(run.record))
            print(f"wrote {paths[0].parent}/: " + " ".join(p.name for p in paths) + "\n", flush=True)
    return 0


def _report(args) -> int:
    """``study report FOLDER``: the Markdown page of the study results in FOLDER."""
    if not args.folder:
        raise UsageError("study report needs the folder of study results, e.g. `mdroll study report docs/studies`")
    if not Path(args.folder).is_dir():
        raise UsageError(f"study report: {args.folder!r} is not a folder")
    if args.page:
        check_file_path(Path(args.page), "--page")
    try:
        print(f"wrote {write_page(args.folder, args.page)}")
    except FileNotFoundError as exc:
        raise UsageError(str(exc)) from None
    return 0
