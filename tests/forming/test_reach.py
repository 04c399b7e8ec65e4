"""What the press can make of a plate: overhang, edge error, pitch, stroke room (mppf/forming/reach.py)."""

from __future__ import annotations

import numpy as np

from mppf.forming.reach import reach_estimate
from mppf.loop.plate import plate_reach


def test_a_bundled_plate_is_within_reach_and_says_so(planned_plate):
    design, _, press, job = planned_plate
    reach = reach_estimate(press, job, design.points, 2.5)
    # the net plate ends a quarter pitch beyond the outer punch axes: its free edge is nearly the design's
    assert 0.0 < reach.overhang_mm <= 0.5 * reach.pitch_mm[0] and reach.pitch_mm == (150.0, 150.0)
    assert 0.0 <= reach.edge_error_mm < 0.5 and reach.reachable
    assert 0.0 < reach.stroke_room_mm < press.lower.max_mm - press.lower.min_mm
    assert "within reach" in reach.text and plate_reach(press, job, design.points, 2.5)["reachable"]


def test_a_plate_far_beyond_its_outer_punches_is_not_within_reach(planned_plate):
    design, _, press, job = planned_plate
    # only the inner punches active: the net plate overhangs them by several pitches
    final = job.steps[-1]
    inner = np.zeros_like(final.active)
    inner[3:-3, 4:-4] = final.active[3:-3, 4:-4]
    step = type(final)(np.where(inner, final.upper_mm, np.nan), np.where(inner, final.lower_mm, np.nan), inner)
    narrow = type(job)(press=job.press, thickness_mm=job.thickness_mm, steps=[step], tf_press_design=job.tf_press_design,
                       tf_press_flat=job.tf_press_flat, punch_x_mm=job.punch_x_mm, punch_y_mm=job.punch_y_mm,
                       layout=job.layout)
    reach = reach_estimate(press, narrow, design.points, 2.5)
    assert reach.overhang_mm > 300.0 and reach.edge_error_mm > 1.25 and not reach.reachable
    assert "may not be reached" in reach.text
