"""``mdroll merge``: the spectra of runs over disjoint realizations, merged into one run's outputs."""

from __future__ import annotations

from pathlib import Path

from ..ensemble.result import EnsembleResult
from ..errors import UsageError
from ..files import remove_stale_temporaries
from .common import check_output, output_dir, output_options
from .run import RUN_OUTPUTS, write_outputs


def add_parser(sub) -> None:
    p = sub.add_parser("merge", help="merge the spectra.npz of runs over disjoint realizations into one")
    p.add_argument("inputs", nargs="+", metavar="RUN", help="run directories or spectra.npz files")
    output_options(p)


def execute(args) -> int:
    paths = [Path(p) / "spectra.npz" if Path(p).is_dir() else Path(p) for p in args.inputs]
    missing = [str(p) for p in paths if not p.is_file()]
    if missing:
        raise UsageError(f"no spectra.npz at {', '.join(missing)}")
    check_output(args)
    result = EnsembleResult.merge([EnsembleResult.load(p) for p in paths])
    out = output_dir(args, clear=RUN_OUTPUTS)
    for name in RUN_OUTPUTS:  # the directory is locked: no other writer
        remove_stale_temporaries(out / name)
    write_outputs(result, out)
    return 0
