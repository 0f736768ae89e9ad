"""``mdroll params``: every parameter and derived quantity, with units."""

from __future__ import annotations

from .common import build_params, format_value, param_options

UNITS = {"E": "Pa", "nu": "-", "R": "m", "m": "kg", "F_N": "N", "v0": "m/s", "L": "m", "dx": "m", "h0": "m",
         "H": "-", "q_min": "rad/m", "q_max": "rad/m", "n_real": "-", "q_r": "rad/m"}


def add_parser(sub) -> None:
    p = sub.add_parser("params", help="print every parameter and derived quantity with units")
    param_options(p)


def execute(args) -> int:
    p = build_params(args)
    print("parameters")
    for key, value in p.as_dict().items():
        print(f"  {key:<10} {format_value(value):>14}  {UNITS.get(key, '')}")
    print("derived")
    for key, (value, unit, text) in p.derived().items():
        print(f"  {key:<18} {format_value(value):>14}  {unit:<9} {text}")
    return 0
