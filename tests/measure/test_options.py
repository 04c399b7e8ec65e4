"""The options of a comparison, checked once when built (mppf.measure.options)."""

import numpy as np
import pytest

from mppf.core.errors import InputError
from mppf.measure.compare import compare
from mppf.measure.options import CompareOptions


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"tolerance_mm": 0.0}, "tolerance"),
        ({"rms_tolerance_mm": -1.0}, "RMS tolerance"),
        ({"offset_mm": float("nan")}, "skin offset"),
        ({"margin_mm": -5.0}, "trim margin"),
        ({"gap_mm": 300.0, "max_gap_mm": 100.0}, "largest allowed gap"),
        ({"punch_xy_mm": np.zeros((2, 2)), "tf_press_design": np.eye(4)}, "rows, cols, 2"),
        ({"punch_xy_mm": np.zeros((2, 2, 2))}, "tf_press_design"),
        ({"tf_press_design": np.eye(3)}, "4x4"),
        ({"bins": 0}, "bins"),
        ({"bins": [1.0, 0.0]}, "increasing"),
        ({"punch_radius_mm": 0.0}, "punch radius"),
        ({"expected_points": 0}, "expected point count"),
        ({"rotation_hint": np.eye(2)}, "rotation_hint"),
        ({"reference_mark": (np.zeros(2), np.zeros(3))}, "reference_mark"),
        ({"start_from": np.eye(3)}, "start_from"),
        ({"scan_index": np.zeros(5)}, "scan_index"),
    ],
)
def test_bad_options_are_refused_when_built(kwargs, words):
    with pytest.raises(InputError, match=words) as err:
        CompareOptions(**kwargs)
    assert err.value.hint  # what to do


def test_defaults_and_the_outline_fit_follow_the_punch_grid():
    options = CompareOptions()
    assert (options.tolerance_mm, options.rms_tolerance_mm, options.margin_mm) == (2.5, 1.0, 0.0)
    assert not options.outline_fitted
    on_press = CompareOptions(punch_xy_mm=np.zeros((2, 3, 2)), tf_press_design=np.eye(4))
    assert on_press.outline_fitted and on_press.punch_xy_mm.shape == (2, 3, 2)
    assert not CompareOptions(punch_xy_mm=np.zeros((2, 3, 2)), tf_press_design=np.eye(4), fit_outline=False).outline_fitted
    with pytest.raises(AttributeError):
        options.tolerance_mm = 1.0


def test_compare_takes_only_its_options_object():
    points = np.random.default_rng(0).normal(size=(50, 3))
    with pytest.raises(InputError, match="CompareOptions"):
        compare(points, points, {"tolerance_mm": 2.5})
