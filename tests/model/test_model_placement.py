"""Where to lay the plate (``mppf/model/placement.py``): corners of the cut outline, corner A at the mark."""

from __future__ import annotations

import numpy as np

from panel_helpers import CUT_MM, layout_job, rectangle

from mppf.model.placement import outline_corners, placement_of


def test_collinear_points_are_not_corners():
    outline = rectangle(CUT_MM, points_per_side=5)
    assert len(outline) == 20
    np.testing.assert_allclose(outline_corners(outline), CUT_MM)


def test_a_gentle_arc_is_not_a_corner_but_a_chamfer_is():
    arc = [(1000 * np.cos(t), 1000 * np.sin(t)) for t in np.linspace(0, np.pi / 2, 10)]
    outline = np.array([(0.0, 0.0)] + arc)
    corners = outline_corners(outline)
    assert 3 <= len(corners) < len(outline)
    assert any(np.allclose(c, (0.0, 0.0)) for c in corners)
    chamfered = np.array([(0, 0), (1000, 0), (1000, 800), (900, 900), (0, 900)], dtype=float)
    assert len(outline_corners(chamfered)) == 5


def test_corner_a_is_the_cut_corner_at_the_mark_and_the_rest_follow_counter_clockwise():
    placement = placement_of(layout_job().layout)
    np.testing.assert_allclose(placement.mark_mm, (-1200.0, -800.0))  # the corner of the plate as cut at R1 C1
    rows = placement.rows()
    assert [r["name"] for r in rows] == ["A", "B", "C", "D"]
    assert rows[0]["mark"] and not any(r["mark"] for r in rows[1:])
    assert [(r["x_mm"], r["y_mm"]) for r in rows] == [tuple(c) for c in CUT_MM]
    assert len(placement.net_corners_mm) == 4
