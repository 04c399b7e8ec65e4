"""What the stroke compensation exchanges (mppf.correct.result): punch grids checked against the press's shape."""

from __future__ import annotations

import numpy as np
import pytest
from driver_helpers import small_press

from mppf.core.errors import InputError
from mppf.correct.result import punch_grid


def test_a_punch_grid_of_the_press_s_shape_is_taken_as_floats():
    press = small_press(4, 6)
    grid = punch_grid(press, np.arange(24, dtype=int).reshape(4, 6), "the strokes")
    assert grid.dtype == float and grid.shape == (4, 6) and grid[3, 5] == 23.0


@pytest.mark.parametrize("shape", [(6, 4), (4, 5), (24,)])
def test_another_shape_is_refused_naming_the_grid_and_both_shapes(shape):
    with pytest.raises(InputError, match=rf"the deviations has shape \({shape[0]},.*\), the press has \(4, 6\)"):
        punch_grid(small_press(4, 6), np.zeros(shape), "the deviations")

