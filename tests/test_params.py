"""Params: thesis defaults, derived quantities against hand values, and every bad value rejected."""

import math

import numpy as np
import pytest

from mdroll.errors import ParameterError
from mdroll import Params
from mdroll.checks import (check_nonnegative, check_number, check_positive, check_real,
                           first_negative_or_nonfinite)
from mdroll.ensemble.realizations import read_params


def test_defaults_and_derived_against_hand_values():
    p = Params()
    E_star = 210e9 / (2 * (1 - 0.09))
    assert p.E_star == pytest.approx(E_star, rel=1e-15)
    d0 = (3 * 40e3 / (4 * E_star * math.sqrt(0.5))) ** (2 / 3)
    assert p.d0 == pytest.approx(d0, rel=1e-15)
    assert p.d0 == pytest.approx(51.32e-6, rel=1e-3)  # physics.md section 1
    assert p.a == pytest.approx(5.066e-3, rel=1e-3)
    assert p.F_hertz == pytest.approx(40e3, rel=1e-12)
    assert p.k_contact == pytest.approx(2 * E_star * p.a, rel=1e-15)
    assert p.omega_0 == pytest.approx(1529, rel=1e-3)  # physics.md section 5
    assert p.n_points == 1_000_000
    assert p.dt == pytest.approx(5e-7)
    assert p.q_max == pytest.approx(math.pi / 5e-6)
    assert p.springs_in_contact == pytest.approx(2026, rel=1e-3)
    assert p.dq == pytest.approx(2 * math.pi / 5.0, rel=1e-15)


def test_lambda_A_discrete_normalization_and_continuum_limit():
    p = Params(L=0.5)
    dq = 2 * math.pi / p.length
    k = np.arange(1, p.n_points // 2 + 1)
    q = dq * k
    band = (q >= p.q_min) & (q <= p.q_max)
    # the two-sided PSD integrates to h0^2 (physics.md section 3)
    assert 2 * dq * np.sum(p.lambda_A * q[band] ** (-2 * p.H - 1)) == pytest.approx(p.h0**2, rel=1e-13)
    # continuum limit H h0^2 q_min^(2H), within the discretization of the band edge
    assert p.lambda_A == pytest.approx(p.H * p.h0**2 * p.q_min ** (2 * p.H), rel=0.03)


def test_replace_revalidates_and_follows_nyquist():
    p = Params().replace(dx=20e-6, L=0.2)
    assert p.q_max == pytest.approx(math.pi / 20e-6)
    with pytest.raises(ParameterError, match="H"):
        p.replace(H=1.2)
    with pytest.raises(ParameterError, match="unknown parameter"):
        p.replace(hurst=0.5)


BAD = [
    ("H", 0.0), ("H", 1.0), ("H", -0.3), ("H", float("nan")),
    ("E", 0.0), ("E", -1.0), ("E", float("inf")), ("R", 0.0), ("m", -5.0), ("F_N", float("nan")),
    ("v0", 0.0), ("L", -1.0), ("dx", 0.0), ("h0", 0.0), ("h0", float("inf")),
    ("nu", 0.5), ("nu", -1.0), ("nu", 0.7),
    ("q_min", 0.0), ("q_min", 1e6),  # q_min >= q_max
    ("q_max", 1e7),  # above the Nyquist pi/dx = 6.28e5
    ("dx", 600e-6),  # a/dx < 10
    ("L", 0.015),  # L < 4a
    ("n_real", 0), ("n_real", 2.5), ("E", "210e9"), ("H", True),
]


@pytest.mark.parametrize("name,value", BAD, ids=[f"{n}={v!r}" for n, v in BAD])
def test_bad_values_name_the_parameter(name, value):
    """Through the one reader of parameter dicts, which takes the run's count n_real too."""
    with pytest.raises(ParameterError) as info:
        read_params({name: value})
    message = str(info.value)
    assert message.split()[0].startswith(name) or f"{name} " in message, message
    assert isinstance(info.value, ValueError)


@pytest.mark.parametrize("L", [0.05, 0.2, 5.24288])
@pytest.mark.parametrize("q_min", [2 * math.pi / 0.005, 2 * math.pi / 0.0123, 100.0])
@pytest.mark.parametrize("q_max_fraction", [None, 0.25, 0.999])
def test_mode_range_is_the_band_of_the_grid(L, q_min, q_max_fraction):
    """The generated modes (found without an array over the grid) against the mask of every q_k."""
    p = Params(L=L, q_min=q_min)
    if q_max_fraction:
        p = p.replace(q_max=q_max_fraction * math.pi / p.dx)
    k = np.arange(1, p.n_points // 2 + 1)
    inside = k[p.in_band(2 * math.pi * k / p.length)]
    assert p.mode_range == (inside[0], inside[-1])


CHECK_CASES = [
    (check_positive, ("E", -1.0), "E = -1.0 is not allowed: it must be positive and finite"),
    (check_positive, ("d", math.inf, "m"), "d = inf is not allowed: it must be positive and finite (m)"),
    (check_positive, ("E", "210e9"), "E = '210e9' is not allowed: it must be a real number, positive and finite, "
                                     "not a str"),
    (check_nonnegative, ("loss", np.float64(-0.1)), "loss = np.float64(-0.1) is not allowed: it must be zero or"),
    (check_real, ("h_max", np.True_), "h_max = np.True_ is not allowed: it must be a real number, finite, not a bool"),
    (check_real, ("h_max", math.nan, "m"), "h_max = nan is not allowed: it must be finite (m)"),
]


@pytest.mark.parametrize("check,args,message", CHECK_CASES, ids=[c[2].split(" is")[0] for c in CHECK_CASES])
def test_the_number_checks_name_the_value_and_what_is_allowed(check, args, message):
    with pytest.raises(ParameterError) as raised:
        check(*args)
    assert str(raised.value).startswith(message)


def test_the_number_checks_pass_real_numbers_of_every_kind_as_floats():
    values = [check_positive("a", 2), check_positive("a", np.int32(2)), check_nonnegative("a", 0.0),
              check_real("a", np.float32(-2.0)), check_number("H", 0.5, "in (0, 1)", lambda v: 0 < v < 1)]
    assert values == [2.0, 2.0, 0.0, -2.0, 0.5] and all(type(v) is float for v in values)


@pytest.mark.parametrize("values, expected", [
    ([0.0, 1.0, 2.0], None), ([0.0, np.nan, -1.0], 1), ([1.0, 2.0, -1e-300], 2), ([np.inf], 0), ([], None)])
def test_the_spectrum_check_finds_the_first_bad_entry(values, expected):
    assert first_negative_or_nonfinite(np.asarray(values, dtype=np.float64)) == expected
