"""Checks of a number's value, made once where a parameter enters (:class:`~mdroll.params.Params`,
:class:`~mdroll.track.Track`, :class:`~mdroll.wheel.Wheel`, the public API's arguments): a bad
value ends in one :class:`~mdroll.errors.ParameterError` naming the parameter, the value and what
is allowed. Below every layer that takes parameters, so that all of them check alike.
"""

from __future__ import annotations

import math

import numpy as np

from .errors import ParameterError


def is_real(value) -> bool:
    """Whether ``value`` is a real number: a Python or NumPy int or float, not a bool."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def check_number(name: str, value, allowed: str, admits, unit: str = "") -> float:
    """``value`` as a float if it is a real number that ``admits`` (a test of that float) accepts;
    else ParameterError: ``name = value is not allowed: it must be <allowed> (<unit>)``."""
    real = is_real(value)
    if not (real and admits(float(value))):
        what = f"{allowed} ({unit})" if unit else allowed
        what = what if real else f"a real number, {what}, not a {type(value).__name__}"
        raise ParameterError(f"{name} = {value!r} is not allowed: it must be {what}")
    return float(value)


def check_positive(name: str, value, unit: str = "") -> float:
    """``value`` as a float if it is a positive, finite real number."""
    return check_number(name, value, "positive and finite", lambda v: math.isfinite(v) and v > 0, unit)


def check_nonnegative(name: str, value, unit: str = "") -> float:
    """``value`` as a float if it is a finite real number, zero or positive."""
    return check_number(name, value, "zero or positive and finite", lambda v: math.isfinite(v) and v >= 0, unit)


def check_real(name: str, value, unit: str = "") -> float:
    """``value`` as a float if it is a finite real number."""
    return check_number(name, value, "finite", math.isfinite, unit)


def first_negative_or_nonfinite(values: np.ndarray) -> int | None:
    """Index of the first entry of ``values`` that is not finite or is negative (a spectrum, a
    variance or a standard error must be neither), or None if every entry is finite and >= 0."""
    bad = ~np.isfinite(values) | (values < 0)
    return int(np.argmax(bad)) if bad.any() else None
