"""Multi-step split and the validation of planned strokes, unit by unit."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import LimitError
from mppf.core.grid import neighbour_differences
from mppf.planning.job import StepStrokes
from mppf.planning.press import example_press_path, load_press
from mppf.planning.steps import split_steps, steps_needed, validate_steps

PRESS = load_press(example_press_path())
T = 20.0


def _flat_step(active=None):
    active = np.ones(PRESS.shape, bool) if active is None else active
    return StepStrokes(upper_mm=np.where(active, T, np.nan), lower_mm=np.where(active, 0.0, np.nan),
                       active=active)


def test_neighbour_differences_find_rows_and_columns():
    values = np.zeros((3, 4))
    values[1, 2] = 5.0
    active = np.ones((3, 4), bool)
    active[0, 2] = False
    (dx, ax, bx), (dy, ay, by) = neighbour_differences(values, active)
    # along x: (1,1)-(1,2) = +5 and (1,2)-(1,3) = -5
    pairs_x = {(tuple(a), tuple(b)): d for d, a, b in zip(dx, ax, bx) if d}
    assert pairs_x == {((1, 1), (1, 2)): 5.0, ((1, 2), (1, 3)): -5.0}
    # along y: (0,2) is inactive, so only (1,2)-(2,2) = -5
    pairs_y = {(tuple(a), tuple(b)): d for d, a, b in zip(dy, ay, by) if d}
    assert pairs_y == {((1, 2), (2, 2)): -5.0}


def test_split_steps_are_equal_fractions_and_steps_needed():
    active = np.ones(PRESS.shape, bool)
    upper = np.full(PRESS.shape, T)
    lower = np.zeros(PRESS.shape)
    upper[5, 5] += 70.0
    lower[5, 5] += 70.0
    n = steps_needed(upper, lower, active, PRESS, T)
    assert n == 3  # 70 mm neighbour difference, 30 mm per step
    steps = split_steps(upper, lower, active, T, n)
    np.testing.assert_allclose([s.lower_mm[5, 5] for s in steps], [70 / 3, 140 / 3, 70.0])
    report = validate_steps(steps, PRESS, T)
    assert report["max_neighbour_step_mm"] == pytest.approx(70 / 3)
    with pytest.raises(LimitError, match=r"step 1 upper\[5,5\]-upper\[5,6\].*dimpling"):
        validate_steps(split_steps(upper, lower, active, T, 2), PRESS, T)


def test_validation_lists_limit_gap_and_reversal_problems():
    bad = _flat_step()
    bad.upper_mm[2, 3] = 500.0
    with pytest.raises(LimitError, match=r"upper\[2,3\] stroke 500.00 mm outside -300..400"):
        validate_steps([bad], PRESS, T)
    squeezed = _flat_step()
    squeezed.upper_mm[4, 7] = T - 0.5
    with pytest.raises(LimitError, match=r"pair\[4,7\] tip gap 19.50 mm < thickness 20"):
        validate_steps([squeezed], PRESS, T)
    there = _flat_step()
    there.lower_mm[1, 1] = there.upper_mm[1, 1] = 10.0
    there.upper_mm[1, 1] = 30.0
    back = _flat_step()
    with pytest.raises(LimitError, match=r"step 2 pair\[1,1\] reverses direction"):
        validate_steps([there, back], PRESS, T)
    # inactive punches are not checked
    parked = _flat_step()
    parked.active[0, 0] = False
    parked.upper_mm[0, 0] = np.nan
    assert validate_steps([parked], PRESS, T)["passed"]
