"""The press description (``mppf/model/press.py``): loading, validation in the dataclasses and every ConfigError."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mppf.core.errors import ConfigError
from mppf.model.press import AxisLimits, PressConfig, example_press_path, load_press, press_from_dict

EXAMPLE = load_press(example_press_path())


def _doc(**changes) -> dict:
    """The example press as a dict, with ``table__key=value`` changes (value None deletes)."""
    doc = EXAMPLE.to_dict()
    for key, value in changes.items():
        table, name = key.split("__")
        if value is None:
            del doc[table][name]
        else:
            doc[table][name] = value
    return doc


def test_example_press_is_the_one_the_issue_describes():
    press = EXAMPLE
    assert (press.rows, press.cols) == (16, 24)
    assert press.pitch_x_mm == press.pitch_y_mm == 150.0
    assert press.tip_radius_mm == 60.0
    assert press.upper == AxisLimits(-300.0, 400.0, 400.0)
    assert press.lower == AxisLimits(-400.0, 300.0, -400.0)
    assert press.max_neighbour_diff_mm == 30.0 and press.speed_mm_s == 20.0
    # punch axes centred on 0, x along the longer axis
    assert press.punch_x_mm.shape == (24,) and press.punch_y_mm.shape == (16,)
    np.testing.assert_allclose(press.punch_x_mm[[0, -1]], [-1725.0, 1725.0])
    np.testing.assert_allclose(press.punch_y_mm[[0, -1]], [-1125.0, 1125.0])
    assert press.bed_size_mm == (3450.0, 2250.0)


def test_round_trip_through_the_dict_layout():
    assert press_from_dict(EXAMPLE.to_dict(), "x") == EXAMPLE


def test_optional_keys_take_their_defaults():
    doc = _doc(forming__trim_allowance_mm=None, forming__speed_mm_s=None, forming__accel_mm_s2=None,
               forming__position_tolerance_mm=None)
    del doc["name"]
    press = press_from_dict(doc)
    assert (press.trim_allowance_mm, press.speed_mm_s, press.accel_mm_s2, press.position_tolerance_mm) == \
        (100.0, 20.0, 100.0, 0.2)
    assert press.name == "press"


def test_integers_are_accepted_as_millimetres():
    press = press_from_dict(_doc(matrix__pitch_x_mm=160))
    assert press.pitch_x_mm == 160.0 and isinstance(press.pitch_x_mm, float)


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"matrix__rows": None}, "missing key 'rows' in [matrix]"),
        ({"upper__park_mm": None}, "missing key 'park_mm' in [upper]"),
        ({"forming__max_neighbour_diff_mm": None}, "missing key 'max_neighbour_diff_mm'"),
        ({"matrix__tip_radus_mm": 60.0}, "unknown key(s) ['tip_radus_mm'] in [matrix]"),
        ({"matrix__rows": "16"}, "[matrix] rows must be a whole number, got '16'"),
        ({"matrix__rows": 16.0}, "[matrix] rows must be a whole number, got 16.0"),
        ({"matrix__rows": True}, "[matrix] rows must be a whole number"),
        ({"matrix__pitch_x_mm": "150 mm"}, "[matrix] pitch_x_mm must be a number, got '150 mm'"),
        ({"upper__max_mm": False}, "[upper] max_mm must be a number, got False"),
        ({"matrix__pitch_y_mm": float("nan")}, "[matrix] pitch_y_mm must be a finite number, got nan"),
        ({"lower__min_mm": float("-inf")}, "[lower] min_mm must be a finite number, got -inf"),
        ({"matrix__pitch_x_mm": 1e308}, "[matrix] pitch_x_mm must be above 0 and at most 1e+06 mm, got 1e+308"),
        ({"upper__max_mm": 2e6}, "[upper] max_mm must be from -1e+06 to 1e+06 mm, got 2000000.0"),
        ({"matrix__rows": 0}, "[matrix] rows must be from 1 to 32, got 0"),
        ({"matrix__cols": 33}, "[matrix] cols must be from 1 to 32, got 33"),
        ({"matrix__pitch_x_mm": 0.0}, "[matrix] pitch_x_mm must be above 0 and at most 1e+06 mm, got 0.0"),
        ({"matrix__tip_radius_mm": -60.0}, "[matrix] tip_radius_mm must be above 0 and at most 1e+06 mm, got -60.0"),
        ({"forming__max_neighbour_diff_mm": 0.0}, "[forming] max_neighbour_diff_mm must be above 0 and at most 1e+06 mm, got 0.0"),
        ({"forming__speed_mm_s": -1.0}, "[forming] speed_mm_s must be above 0 and at most 1e+06 mm/s, got -1.0"),
        ({"forming__trim_allowance_mm": -5.0}, "[forming] trim_allowance_mm must be from 0 to 1e+06 mm, got -5.0"),
        ({"matrix__tip_radius_mm": 80.0}, "tip_radius_mm 80.0 is too large for the pitch"),
        ({"upper__min_mm": 400.0}, "[upper] min_mm (400.0) must be below max_mm (400.0)"),
        ({"lower__park_mm": 301.0}, "[lower] park_mm (301.0) must lie within min_mm..max_mm"),
    ],
)
def test_each_bad_key_is_a_config_error_naming_key_and_value(changes, message):
    with pytest.raises(ConfigError) as info:
        press_from_dict(_doc(**changes), "press.toml")
    assert message in info.value.message
    assert info.value.message.startswith("press.toml")


def test_bad_tables_and_names():
    with pytest.raises(ConfigError, match="expected a table"):
        press_from_dict([1, 2])
    doc = _doc()
    doc["matrx"] = doc.pop("matrix")
    with pytest.raises(ConfigError, match=r"unknown table\(s\) \['matrx'\]"):
        press_from_dict(doc)
    doc = _doc()
    del doc["lower"]
    with pytest.raises(ConfigError, match=r"missing table \[lower\]"):
        press_from_dict(doc)
    doc = _doc()
    doc["forming"] = 3
    with pytest.raises(ConfigError, match=r"missing table \[forming\]"):
        press_from_dict(doc)
    doc = _doc()
    doc["name"] = 42
    with pytest.raises(ConfigError, match="name must be a string, got 42"):
        press_from_dict(doc)


def test_load_press_file_errors(tmp_path):
    with pytest.raises(ConfigError, match="does not exist"):
        load_press(tmp_path / "missing.toml")
    with pytest.raises(ConfigError, match="is a directory"):
        load_press(tmp_path)
    bad = tmp_path / "bad.toml"
    bad.write_text("[matrix\nrows = 16\n")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_press(bad)
    binary = tmp_path / "binary.toml"
    binary.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(ConfigError):
        load_press(binary)
    empty = tmp_path / "empty.toml"
    empty.write_text("")
    with pytest.raises(ConfigError, match=r"missing table \[matrix\]"):
        load_press(empty)
    nan = tmp_path / "nan.toml"
    nan.write_text(example_press_path().read_text().replace("pitch_x_mm = 150.0", "pitch_x_mm = nan"))
    with pytest.raises(ConfigError, match=r"pitch_x_mm must be a finite number"):
        load_press(nan)


def test_config_errors_carry_the_input_exit_code():
    with pytest.raises(ConfigError) as info:
        press_from_dict(_doc(matrix__rows=0))
    assert info.value.exit_code == 2


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"rows": 0}, "[matrix] rows must be from 1 to 32, got 0"),
        ({"cols": 2.5}, "[matrix] cols must be a whole number, got 2.5"),
        ({"pitch_y_mm": float("nan")}, "[matrix] pitch_y_mm must be a finite number, got nan"),
        ({"tip_radius_mm": 80.0}, "tip_radius_mm 80.0 is too large for the pitch"),
        ({"speed_mm_s": 0.0}, "[forming] speed_mm_s must be above 0 and at most 1e+06 mm/s, got 0.0"),
        ({"margin_mm": -1.0}, "[forming] margin_mm must be from 0 to 1e+06 mm, got -1.0"),
        ({"name": 42}, "name must be a string, got 42"),
        ({"upper": (-300.0, 400.0, 400.0)}, "[upper] must be the tip-height limits"),
    ],
)
def test_a_press_built_in_code_is_checked_like_one_read_from_a_file(changes, message):
    with pytest.raises(ConfigError) as info:
        dataclasses.replace(EXAMPLE, **changes)
    assert message in info.value.message


def test_axis_limits_built_in_code_are_checked():
    with pytest.raises(ConfigError, match=r"min_mm \(400.0\) must be below max_mm \(300.0\)"):
        AxisLimits(400.0, 300.0, 300.0)
    with pytest.raises(ConfigError, match="park_mm must be a finite number"):
        AxisLimits(-300.0, 400.0, float("nan"))
    limits = AxisLimits(-300, 400, 400)  # whole numbers are millimetres too
    assert limits == AxisLimits(-300.0, 400.0, 400.0) and isinstance(limits.min_mm, float)


def test_a_valid_press_built_in_code_keeps_its_values_and_defaults():
    press = PressConfig(rows=4, cols=6, pitch_x_mm=160, pitch_y_mm=150.0, tip_radius_mm=60.0,
                        upper=EXAMPLE.upper, lower=EXAMPLE.lower, max_neighbour_diff_mm=30.0)
    assert press.shape == (4, 6) and isinstance(press.pitch_x_mm, float)
    assert (press.trim_allowance_mm, press.speed_mm_s, press.margin_mm, press.name) == (100.0, 20.0, 0.0, "press")
    assert press_from_dict(press.to_dict()) == press


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"upper__park_mm": -300.0, "lower__park_mm": 300.0},
         "[upper] park_mm -300 mm is below [lower] park_mm 300 mm: the parked tips would cross"),
        ({"upper__park_mm": 20.0, "lower__park_mm": 0.0},
         "[upper] park_mm 20 mm and [lower] park_mm 0 mm leave 20 mm between the parked tips, less than the largest "
         "plate thickness [forming] max_thickness_mm 50 mm"),
        ({"upper__park_mm": 60.0, "lower__park_mm": 0.0, "forming__max_thickness_mm": 80.0},
         "leave 60 mm between the parked tips, less than the largest plate thickness [forming] max_thickness_mm 80 mm"),
        ({"forming__max_thickness_mm": 0.0}, "[forming] max_thickness_mm must be above 0"),
        ({"matrix__label_base": 2}, "[matrix] label_base must be from 0 to 1, got 2"),
        ({"matrix__label_base": 1.0}, "[matrix] label_base must be a whole number, got 1.0"),
    ],
)
def test_parking_heights_must_leave_room_for_the_thickest_plate(changes, message):
    with pytest.raises(ConfigError) as info:
        press_from_dict(_doc(**changes), "press.toml")
    assert message in info.value.message and info.value.message.startswith("press.toml")


def test_parks_exactly_the_thickest_plate_apart_and_the_punch_labels():
    press = press_from_dict(_doc(upper__park_mm=50.0, lower__park_mm=0.0))
    assert press.upper.park_mm - press.lower.park_mm == press.max_thickness_mm == 50.0
    assert EXAMPLE.label_base == 1 and EXAMPLE.punch_label(0, 0) == "row 1, col 1"
    assert press_from_dict(_doc(matrix__label_base=0)).punch_label(2, 3) == "row 2, col 3"
    assert press_from_dict(EXAMPLE.to_dict()) == EXAMPLE  # the new keys go through the dict layout
