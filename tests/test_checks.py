"""The shared argument checks: ranges, types, messages naming the argument."""

from __future__ import annotations

import math

import numpy as np
import pytest

from spa import ValveParams, modulate
from spa import _checks as checks
from spa.model.averaging import equilibrium, time_fractions
from spa.model.params import valve_params
from spa.tuning import linearity_cost


@pytest.mark.parametrize("bad", [True, np.bool_(False), "20", None, [1.0]])
def test_numbers_refuse_booleans_strings_and_containers(bad):
    with pytest.raises(checks.ArgumentTypeError, match="f_w must be a number"):
        checks.positive("f_w", bad)


def test_type_errors_are_also_value_errors():
    with pytest.raises(TypeError):
        checks.integer("n_xi", 10.0)
    with pytest.raises(ValueError):
        checks.integer("n_xi", 10.0)


@pytest.mark.parametrize("bad", [0.0, -1.0, math.inf, math.nan])
def test_positive_names_the_argument_and_the_range(bad):
    with pytest.raises(ValueError, match=r"dt must be finite and > 0 s, got"):
        checks.positive("dt", bad, "s")


def test_nonnegative_accepts_zero_only_from_below():
    assert checks.nonnegative("skip", 0) == 0.0
    with pytest.raises(ValueError, match=r"skip must be finite and >= 0"):
        checks.nonnegative("skip", -1e-12)


@pytest.mark.parametrize(
    ("kwargs", "value", "interval"),
    [
        ({}, 1.5, r"\[0, 1\]"),
        ({"low_open": True}, 0.0, r"\(0, 1\]"),
        ({"high_open": True}, 1.0, r"\[0, 1\)"),
    ],
)
def test_fraction_writes_its_interval(kwargs, value, interval):
    with pytest.raises(ValueError, match=f"settle must be a fraction in {interval}"):
        checks.fraction("settle", value, **kwargs)
    assert checks.fraction("settle", 0.5, **kwargs) == 0.5


def test_integer_minimum():
    assert checks.integer("n", np.int64(3), minimum=2) == 3
    with pytest.raises(ValueError, match="n must be an integer >= 2, got 1"):
        checks.integer("n", 1, minimum=2)


def test_finite_array_reports_the_first_bad_index_in_any_dimension():
    with pytest.raises(ValueError, match=r"xi\[1, 0\] = inf"):
        checks.finite_array("xi", [[0.0, 1.0], [np.inf, 0.0]])
    with pytest.raises(ValueError, match="one-dimensional"):
        checks.finite_array("xi", [[0.0]], ndim=1)
    with pytest.raises(ValueError, match="at least 2"):
        checks.finite_array("t", [0.0], min_size=2)
    with pytest.raises(checks.ArgumentTypeError, match="numeric"):
        checks.finite_array("xi", "abc")


def test_positive_array():
    np.testing.assert_array_equal(checks.positive_array("t_l", [0.01, 0.02]), [0.01, 0.02])
    with pytest.raises(ValueError, match=r"t_l\[2\] = -0.1"):
        checks.positive_array("t_l", [0.01, 0.02, -0.1])


def test_valve_params():
    assert valve_params(None) == ValveParams()
    with pytest.raises(checks.ArgumentTypeError, match="params must be a ValveParams, got dict"):
        valve_params({"c1": 1.0})


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda: modulate("pwm", [0.5] * 4, True, f_w=20), "dt must be a number"),
        (lambda: modulate("pwm", [0.5] * 4, 1e-3, f_w=True), "pwm: setting 'f_w'"),
        (lambda: time_fractions("iipfm", 0.5, None, t_l=[0.02, np.nan]), r"'t_l'\[1\] = nan"),
        (lambda: equilibrium("pwm", [[0.5, np.nan]], None, f_w=20), r"xi\[0, 1\]"),
        (lambda: linearity_cost("pwm", 20.0, n_xi=True), "n_xi"),
    ],
)
def test_public_functions_use_the_checks(call, match):
    with pytest.raises(ValueError, match=match):
        call()
