"""The offset and tilt of least travel: the linear programme and the tilt as a rotation."""

from __future__ import annotations

import numpy as np
import pytest
from plan_helpers import press  # noqa: F401 (fixture)

from mppf.core.transform import apply_tf
from mppf.planning.pose import minimax_offset, tilt_tf


def test_minimax_offset_closed_form_and_linear_programme_agree():
    rng = np.random.default_rng(3)
    x, y = rng.uniform(-1500, 1500, 200), rng.uniform(-1000, 1000, 200)
    dev = 0.02 * x - 0.01 * y + rng.normal(0, 3, 200)
    low, high = np.full(200, -400.0), np.full(200, 300.0)
    a, b, c, s = minimax_offset(dev, x, y, low, high, max_slope=0.0)
    assert (a, b) == (0.0, 0.0)
    assert s == pytest.approx(np.ptp(dev) / 2)
    a, b, c, s_tilt = minimax_offset(dev, x, y, low, high, max_slope=0.05)
    assert s_tilt < s / 3
    assert np.abs(dev + a * x + b * y + c).max() == pytest.approx(s_tilt, abs=1e-6)
    assert minimax_offset(dev, x, y, np.full(200, -1.0), np.full(200, 1.0), max_slope=0.0) is None


def test_tilt_adds_the_plane_of_its_slopes_to_a_horizontal_surface():
    centre = np.array([100.0, -50.0, 10.0])
    tf = tilt_tf(0.01, -0.02, centre)
    np.testing.assert_allclose(tf[:3, :3] @ tf[:3, :3].T, np.eye(3), atol=1e-12)  # a rotation
    np.testing.assert_allclose(apply_tf(tf, centre[None])[0], centre, atol=1e-12)  # about the centre
    x, y = np.meshgrid(np.linspace(-1000, 1000, 5), np.linspace(-600, 600, 4))
    flat = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, centre[2])])
    moved = apply_tf(tf, flat)
    # to first order: z' = z + 0.01 (x - x0) - 0.02 (y - y0); second-order terms below 0.5 mm over 1 m
    expected = centre[2] + 0.01 * (flat[:, 0] - centre[0]) - 0.02 * (flat[:, 1] - centre[1])
    np.testing.assert_allclose(moved[:, 2], expected, atol=0.5)
    assert np.abs(moved[:, 2] - expected).max() < 0.05 * np.abs(expected - centre[2]).max()


def test_a_pose_whose_tilt_goes_astray_and_has_no_level_pose_is_refused_with_the_limits(press, monkeypatch):
    """When the tilted pose re-solved leaves no offset within the strokes and the level pose has none either,
    the planner says which strokes are beyond the limits (it fell back to a level pose that did not exist)."""
    from plan_helpers import CylinderSurface

    from mppf.core.errors import LimitError
    from mppf.core.transform import make_tf
    from mppf.planning import pose
    from mppf.planning.contact import PlacedSurface

    best = pose._Travels.best
    monkeypatch.setattr(pose._Travels, "best",
                        lambda self, dev, max_slope: None if max_slope == 0.0 else best(self, dev, max_slope=max_slope))
    placed = PlacedSurface(CylinderSurface(20000.0), make_tf(translation=[0.0, 0.0, 10.0]))
    x, y = (g.ravel() for g in np.meshgrid(press.punch_x_mm[2:-2], press.punch_y_mm[2:-2]))
    with pytest.raises(LimitError, match="beyond the press limits"):
        pose.optimise_pose(placed, x, y, [f"[{i}]" for i in range(x.size)], press, 20.0, np.zeros(3))
