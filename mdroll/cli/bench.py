"""``mdroll bench``: the scaling study of the force algorithms: bench.json, bench.png and a table."""

from __future__ import annotations

from ..bench import format_table, plot_study, run_study
from ..devices import resolve_device
from ..experiments import write_json
from .common import output_dir, output_options, progress_printer, size_options


def add_parser(sub) -> None:
    p = sub.add_parser("bench", help="scaling study of the force algorithms: bench.json, bench.png and a table")
    size_options(p, quick="sizes for a CPU (default)", full="the full study's sizes (GPU)")
    p.add_argument("--device", action="append", help="cpu, cuda or cuda:N (repeatable; default every available one)")
    output_options(p)


def execute(args) -> int:
    devices = [resolve_device(d) for d in args.device] if args.device else None  # before the folder is made
    out = output_dir(args)
    record = run_study(args.size or "quick", devices=devices, progress=progress_printer(args))
    write_json(out / "bench.json", record, indent=2)
    plot_study(record, out / "bench.png")
    print(format_table(record))
    print(f"wrote {out}/: bench.json bench.png")
    return 0
