"""Border steps of a sectional plan on plates whose overlaps are degenerate (real flat-bottom plates)."""

import numpy as np

from mppf.model.press import example_press_path, load_press
from mppf.planning.sectional import plan_plate
from mppf.planning.sectional_borders import _collinear


def test_collinear_points_are_recognised():
    line = np.column_stack([np.full(5, -75.0), np.linspace(0.0, 400.0, 5)])
    assert _collinear(line)
    assert _collinear(line[:1])
    assert not _collinear(np.vstack([line, [[25.0, 0.0]]]))


def test_a_flat_bottom_plate_longer_than_the_bed_is_planned_in_sections():
    """A 6.9 x 2.6 m flat plate (the KCS's flat bottom): some overlaps hold one line of punches only."""
    u, v = np.meshgrid(np.arange(0.0, 6901.0, 100.0), np.arange(0.0, 2601.0, 100.0), indexing="ij")
    flat = np.column_stack([u.ravel(), v.ravel(), np.zeros(u.size)])
    design = flat + np.array([93800.0, 2300.0, 0.0])  # in hull coordinates, as cut at the keel
    job = plan_plate(design, flat, load_press(example_press_path()), 20.0)
    assert len(job.sections) > 1
    assert job.sectional.max_border_step_mm < 0.01
