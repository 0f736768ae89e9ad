"""Checks of the public API's arguments, made once where each enters (:func:`mdroll.contact_force`,
:func:`mdroll.run_ensemble`): a bad value ends in one :class:`~mdroll.errors.ParameterError`
naming the argument, the value and what is allowed. A number's range: :mod:`mdroll.checks`."""

from __future__ import annotations

import numpy as np

from .errors import ParameterError
from .params import Params


def check_params(params) -> Params:
    """``params`` if it is a :class:`~mdroll.params.Params`."""
    if not isinstance(params, Params):
        raise ParameterError(f"params must be an mdroll.Params, got {type(params).__name__}")
    return params


def check_flag(name: str, value) -> bool:
    """``value`` if it is a bool."""
    if not isinstance(value, (bool, np.bool_)):
        raise ParameterError(f"{name} = {value!r} is not allowed: it must be True or False")
    return bool(value)


def check_choice(name: str, value, allowed) -> str:
    """``value`` if it is one of ``allowed``."""
    if not isinstance(value, str) or value not in allowed:
        raise ParameterError(f"{name} = {value!r} is not allowed: choose one of {', '.join(allowed)}")
    return value


def check_integer(name: str, value, minimum: int, unit: str = "", maximum: int | None = None) -> int:
    """``value`` as an int if it is an integer (not a bool) >= ``minimum`` (and <= ``maximum``)."""
    if (isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < minimum
            or (maximum is not None and value > maximum)):
        if maximum is not None:
            allowed = f"an integer from {minimum} to {maximum}"
        else:
            allowed = "a positive integer" if minimum == 1 else f"an integer >= {minimum}"
        raise ParameterError(f"{name} = {value!r} is not allowed: it must be {allowed}{f' ({unit})' if unit else ''}")
    return int(value)


def check_tree_options(leaf_size, band_limit) -> tuple[int, int]:
    """The tree's tuning knobs: ``leaf_size`` >= 1 and ``band_limit`` >= 0 springs."""
    return check_integer("leaf_size", leaf_size, 1, "springs"), check_integer("band_limit", band_limit, 0, "springs")
