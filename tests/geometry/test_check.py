"""The plate checks of points (mppf.geometry.check)."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import GeometryError
from mppf.geometry.check import check_plate


@pytest.fixture()
def cloud():
    rng = np.random.default_rng(7)
    return rng.uniform(-1500.0, 1500.0, size=(50, 3)) + [176000.0, 12000.0, 3000.0]


def test_check_plate_accepts_a_plate(cloud):
    assert check_plate(cloud, min_points=16, source="c.csv").shape == (50, 3)


def test_check_plate_too_few_points(cloud):
    with pytest.raises(GeometryError, match="needs at least 16") as info:
        check_plate(cloud[:10], min_points=16, source="c.csv")
    assert "c.csv" in str(info.value)


def test_check_plate_coincident():
    pts = np.tile([176000.0, 5000.0, 2000.0], (20, 1))
    with pytest.raises(GeometryError, match="coincide"):
        check_plate(pts, min_points=3)


def test_check_plate_collinear_with_noise_far_below_tolerance():
    t = np.linspace(0.0, 3000.0, 40)
    pts = np.column_stack([176000.0 + t, 5000.0 + 0.5 * t, 2000.0 - 0.2 * t])
    pts += np.random.default_rng(3).normal(scale=1e-9, size=pts.shape)
    with pytest.raises(GeometryError, match="collinear"):
        check_plate(pts, min_points=3)
