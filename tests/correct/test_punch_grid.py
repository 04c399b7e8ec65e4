"""Fields on the punch grid (mppf.correct.punch_grid): curvatures of heights, heights of curvatures, fills."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mppf.correct.punch_grid import PunchGrid
from mppf.model.press import example_press_path, load_press

PRESS = dataclasses.replace(load_press(example_press_path()), rows=7, cols=9)
A, B, C = 2.0e-5, -1.0e-5, 0.6e-5
"""A saddle z = A x^2 + B y^2 + C x y (mm): curvature (2A, 2B, 2C) everywhere (1/mm)."""


@pytest.fixture(scope="module")
def grid():
    return PunchGrid(PRESS, np.ones((PRESS.rows, PRESS.cols), dtype=bool))


def _saddle(g: PunchGrid, plane=(0.0, 0.0, 0.0)) -> np.ndarray:
    x, y = g.x_mm, g.y_mm
    return A * x * x + B * y * y + C * x * y + plane[0] + plane[1] * x + plane[2] * y


def test_the_curvature_of_a_saddle_is_its_constant_hessian(grid):
    """Exact two punches in from the edge (central differences of central differences); a plane adds nothing."""
    kappa = grid.curvature(_saddle(grid, (5.0, 1e-3, -2e-3))).reshape(PRESS.rows, PRESS.cols, 3)
    np.testing.assert_allclose(kappa[2:-2, 2:-2], np.broadcast_to([2 * A, 2 * B, 2 * C], (3, 5, 3)), rtol=1e-9)
    np.testing.assert_allclose(kappa, grid.curvature(_saddle(grid)).reshape(kappa.shape), atol=1e-15)


def test_heights_of_a_curvature_are_the_field_without_its_best_plane(grid):
    """The saddle's constant curvature integrates to the saddle (9.5 mm high here) less its best plane."""
    heights = grid.heights(np.tile([2 * A, 2 * B, 2 * C], (PRESS.rows * PRESS.cols, 1)))
    np.testing.assert_allclose(heights, grid.flat(_saddle(grid, (5.0, 1e-3, -2e-3))), atol=1e-8)
    assert np.ptp(heights) > 5.0
    np.testing.assert_allclose(grid.flat(_saddle(grid) * 0.0 + 3.0 + 0.01 * grid.x_mm), 0.0, atol=1e-9)


def test_a_field_known_at_some_punches_is_filled_and_a_plane_kept_exactly():
    active = np.zeros((PRESS.rows, PRESS.cols), dtype=bool)
    active[1:6, 2:8] = True
    part = PunchGrid(PRESS, active)
    plane = 4.0 + 0.02 * part.x_mm - 0.01 * part.y_mm
    np.testing.assert_allclose(part.fill(plane), plane, atol=1e-9)  # a thin-plate spline keeps planes
    values = np.where(active, plane, np.nan)
    values[3, 4] = np.nan  # an unknown value at an active punch is filled from the known ones
    np.testing.assert_allclose(part.active_values(values), plane[active], atol=1e-9)
    field = part.to_field(part.active_values(plane))
    assert np.isnan(field[~active]).all() and np.allclose(field[active], plane[active])
    assert part.shape == (7, 9) and part.heights(np.zeros((active.sum(), 3)))[active].tolist() == [0.0] * 30
