"""Multi-step split, unit by unit (the validation of the strokes: test_validate.py)."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import LimitError
from mppf.core.grid import neighbour_differences
from mppf.model.press import example_press_path, load_press
from mppf.planning.steps import split_steps, steps_needed
from mppf.planning.validate import validate_steps

PRESS = load_press(example_press_path())
T = 20.0


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
    with pytest.raises(LimitError, match=r"step 1 upper punches \(row 6, col 6\) and \(row 6, col 7\).*dimpling"):
        validate_steps(split_steps(upper, lower, active, T, 2), PRESS, T)
