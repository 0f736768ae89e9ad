"""``mdroll params``: every parameter and derived quantity, with units, and the run's realization count."""

from __future__ import annotations

from ..ensemble.realizations import COUNT_KEY, DEFAULT_REALIZATIONS
from .common import build_params, format_value, param_options

UNITS = {"E": "Pa", "nu": "-", "R": "m", "m": "kg", "F_N": "N", "v0": "m/s", "L": "m", "dx": "m", "h0": "m",
         "H": "-", "q_min": "rad/m", "q_max": "rad/m", "n_real": "-", "q_r": "rad/m"}


def add_parser(sub) -> None:
    p = sub.add_parser("params", help="print every parameter and derived quantity with units")
    param_options(p)


def execute(args) -> int:
    p, count = build_params(args)
    given = [(key, "-" if value in (None, "") else format_value(value), UNITS.get(key, ""), "")
             for key, value in p.as_dict().items()]
    given.append((COUNT_KEY, str(DEFAULT_REALIZATIONS if count is None else count), UNITS[COUNT_KEY],
                  "realizations of a run"))
    derived = [(key, format_value(value), unit, text) for key, (value, unit, text) in p.derived().items()]
    names = max(len(row[0]) for row in given + derived)
    values = max(len(row[1]) for row in given + derived)
    units = max(len(row[2]) for row in given + derived)
    for title, rows in (("parameters", given), ("derived", derived)):
        print(title)
        for key, value, unit, text in rows:
            print(f"  {key:<{names}}  {value:>{values}}  {unit:<{units}}  {text}".rstrip())
    return 0
