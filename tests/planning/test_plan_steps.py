"""The planner's shared steps (``mppf/planning/plan_steps.py``): the refusals both planners rely on."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import GeometryError, InputError, LimitError
from mppf.model.press import example_press_path, load_press
from mppf.planning.plan_steps import (
    MAX_MARGIN_MM,
    active_punches,
    check_plan_inputs,
    check_trim,
    on_grid,
    steps_within_limit,
)
from mppf.planning.steps import MAX_STEPS

PRESS = load_press(example_press_path())


def square(centre_xy, half_mm):
    cx, cy = centre_xy
    return np.array([[cx - half_mm, cy - half_mm], [cx + half_mm, cy - half_mm], [cx + half_mm, cy + half_mm],
                     [cx - half_mm, cy + half_mm]])


def test_the_punches_under_a_plate_and_none_off_the_bed():
    centre = (float(PRESS.punch_x_mm.mean()), float(PRESS.punch_y_mm.mean()))
    active = active_punches(PRESS, square(centre, 1.2 * PRESS.pitch_x_mm))
    assert active.shape == PRESS.shape and 1 <= active.sum() < active.size
    grid = on_grid(PRESS, active, np.arange(active.sum(), dtype=float))
    assert np.isnan(grid[~active]).all() and grid[active].tolist() == list(range(int(active.sum())))
    with pytest.raises(LimitError, match="covers no punch axis"):
        active_punches(PRESS, square((PRESS.punch_x_mm.max() + 1e5, 0.0), 10.0))


def test_more_steps_than_a_job_holds_are_refused():
    with pytest.raises(LimitError, match=f"more than the {MAX_STEPS}"):
        steps_within_limit(np.zeros(PRESS.shape), np.zeros(PRESS.shape), np.ones(PRESS.shape, bool), PRESS, 20.0,
                           MAX_STEPS + 1)


def test_a_contact_past_the_trim_allowance_is_refused():
    outline = square((0.0, 0.0), 500.0)
    assert check_trim(np.array([[0.0, 0.0]]), outline, PRESS) == 0.0
    with pytest.raises(GeometryError, match="past the plate edge"):
        check_trim(np.array([[500.0 + PRESS.trim_allowance_mm + 50.0, 0.0]]), outline, PRESS)


def test_the_inputs_are_checked_before_any_work():
    points = np.zeros((10, 3))
    assert check_plan_inputs(points, points, PRESS, 20, None, None, False, 0)[2:] == (20.0, 0.0)
    with pytest.raises(InputError, match="thickness"):
        check_plan_inputs(points, points, PRESS, -1.0, None, None, False, None)
    with pytest.raises(InputError, match="material"):
        check_plan_inputs(points, points, PRESS, 20.0, None, None, True, None)
    with pytest.raises(InputError, match="trim margin"):
        check_plan_inputs(points, points, PRESS, 20.0, None, None, False, MAX_MARGIN_MM + 1.0)
