"""The one numeric validator and the safe names (mppf.core.validate): refusals name the value and the range."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import ConfigError, InputError
from mppf.core.validate import NumberRange, check_name, check_number, check_positive, safe_name


@pytest.mark.parametrize("value, kwargs, message", [
    (True, {}, "must be a number, got True"),
    ("20", {}, "must be a number, got '20'"),
    (float("inf"), {}, "must be a finite number"),
    (0.0, {"low": 0.0, "low_open": True, "unit": "mm"}, "must be above 0 mm, got 0.0 mm"),
    (2.5, {"integer": True}, "must be a whole number"),
    (60, {"integer": True, "low": 1, "high": 50}, "must be from 1 to 50, got 60"),
])
def test_check_number_refuses_with_the_name_the_value_and_the_range(value, kwargs, message):
    with pytest.raises(InputError, match=message) as info:
        check_number("--thing", value, **kwargs)
    assert "--thing" in info.value.message and info.value.hint


def test_check_number_accepts_and_converts():
    assert check_number("n", 3.0, integer=True) == 3 and isinstance(check_number("n", 3.0, integer=True), int)
    assert check_positive("t", np.float64(20.0), unit="mm") == 20.0
    with pytest.raises(ConfigError):
        check_positive("[press] rows", -1, error=ConfigError)


def test_number_range_says_its_range_and_holds_its_numbers():
    assert NumberRange(low=0.0, high=5.0, unit="mm").text() == "from 0 to 5 mm"
    assert NumberRange(low=0.0, low_open=True).text() == "above 0"
    assert NumberRange().text() == "finite"
    assert NumberRange(low=0.0, high=5.0, high_open=True).holds(0.0)
    assert not NumberRange(low=0.0, high=5.0, high_open=True).holds(5.0)
    with pytest.raises(TypeError, match="lo"):
        check_number("n", 1.0, lo=0.0)  # a misspelt limit is a bug in the caller, not a value to ignore


@pytest.mark.parametrize("name", ["B12-P3", "K2_fwd.2", "a" * 64, "0"])
def test_safe_names_pass(name):
    assert check_name("plate id", name) == name


@pytest.mark.parametrize("name", ["", "../x", "a/b", "a\\b", ".x", "-x", "a" * 65, "B12[/]P3", "a b", "x..y", None,
                                  7, "é"])
def test_unsafe_names_are_refused_naming_the_value(name):
    with pytest.raises(InputError, match="plate id") as refused:
        check_name("plate id", name)
    assert repr(name) in refused.value.message and refused.value.hint


def test_safe_name_makes_a_name_check_name_takes():
    for text in ("P3[rev2]", "../../x", "B12 P3", "", "...", "é"):
        assert check_name("id", safe_name(text)) == safe_name(text)
    assert safe_name("P3[rev2]") == "P3_rev2_"
