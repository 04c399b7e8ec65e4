"""The press's limits on a correction: dimpling limit and stroke limits."""

from __future__ import annotations

import numpy as np

from mppf.correct.limits import limit_correction, limited_notes
from plan_helpers import grid, neighbour_diffs, press  # noqa: F401 (fixtures)

THICKNESS_MM = 20.0


def test_corrections_respect_the_dimpling_limit(press, grid):
    px, py, active, lower = grid
    wanted = np.where(active, 0.0, np.nan)
    spike = np.argwhere(active)[len(np.argwhere(active)) // 2]
    wanted[tuple(spike)] = -100.0  # one punch wildly off
    applied, clipped = limit_correction(press, lower + THICKNESS_MM, lower, wanted)
    diffs = neighbour_diffs(applied, active)
    assert diffs.max() <= press.max_neighbour_diff_mm + 1e-6
    assert applied[tuple(spike)] < -press.max_neighbour_diff_mm * 0.5  # still corrected, less
    assert clipped[tuple(spike)]
    assert any("limited" in note for note in limited_notes(press, clipped))
    assert limited_notes(press, np.zeros(press.shape, dtype=bool)) == []


def test_corrections_respect_the_stroke_limits(press, grid):
    px, py, active, _ = grid
    lower = np.where(active, press.lower.max_mm - 2.0, np.nan)  # lower tips near their top
    upper = np.where(active, press.upper.min_mm + 3.0, np.nan)  # (an odd gap, only to test limits)
    applied, clipped = limit_correction(press, upper, lower, np.where(active, 10.0, np.nan))  # raise by 10 mm
    assert np.all((lower + applied)[active] <= press.lower.max_mm + 1e-9)
    assert np.allclose(applied[active], 2.0)
    assert clipped[active].all()
    # lower by 10 mm: the upper matrix stops it
    applied, clipped = limit_correction(press, upper, lower, np.where(active, -10.0, np.nan))
    assert np.all((upper + applied)[active] >= press.upper.min_mm - 1e-9)
    assert np.allclose(applied[active], -3.0)


def test_limit_correction_holds_any_wanted_change_to_the_press_limits(press, grid):
    """Any wanted change (a spike, one past the tips' travel) is held to the dimpling and stroke limits."""
    px, py, active, lower = grid
    wanted = np.where(active, 0.0, np.nan)
    spike = tuple(np.argwhere(active)[len(np.argwhere(active)) // 2])
    wanted[spike] = -60.0  # one punch wildly lower
    applied, clipped = limit_correction(press, lower + THICKNESS_MM, lower, wanted)
    assert neighbour_diffs(applied, active).max() <= press.max_neighbour_diff_mm + 1e-6
    assert applied[spike] < -0.5 * press.max_neighbour_diff_mm and clipped[spike]
    assert np.all(applied[~active] == 0.0)
    high = np.where(active, 1000.0, np.nan)  # past the lower tips' top
    applied, clipped = limit_correction(press, lower + THICKNESS_MM, lower, high)
    assert np.all((lower + applied)[active] <= press.lower.max_mm + 1e-9) and clipped[active].all()
