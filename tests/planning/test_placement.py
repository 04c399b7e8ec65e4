"""The flat plate laid on the bed: centred, long side along x; curved and oversized plates refused."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import GeometryError, LimitError
from mppf.planning.placement import place_flat
from mppf.model.press import example_press_path, load_press, press_from_dict
from plan_helpers import developed_cylinder

PRESS = load_press(example_press_path())
T = 20.0


def test_place_flat_centres_the_plate_along_x():
    flat = developed_cylinder(1e9, 2000.0, 1200.0)
    turned = flat[:, [1, 0, 2]] + [5000.0, -300.0, 42.0]  # long side along y, elsewhere
    placement = place_flat(turned, PRESS, T)
    np.testing.assert_allclose(placement.size_mm, [2000.0, 1200.0], atol=1e-6)
    np.testing.assert_allclose(placement.flat_press_mm[:, 2], T / 2, atol=1e-9)
    np.testing.assert_allclose(placement.flat_press_mm[:, :2].min(axis=0), [-1000.0, -600.0], atol=1e-6)
    np.testing.assert_allclose(np.abs(placement.corners_mm), [[1000.0, 600.0, 0.0]] * 4, atol=1e-6)


def test_place_flat_refuses_a_curved_plate():
    u, v = np.meshgrid(np.linspace(-1000, 1000, 21), np.linspace(-600, 600, 13))
    curved = np.column_stack([u.ravel(), v.ravel(), (v**2 / 2000.0).ravel()])
    with pytest.raises(GeometryError, match="not flat"):
        place_flat(curved, PRESS, T)


def test_place_flat_refuses_a_plate_larger_than_the_bed():
    doc = PRESS.to_dict()
    doc["matrix"]["rows"] = 6
    small = press_from_dict(doc)
    with pytest.raises(LimitError, match=r"does not fit on the bed .*\(3450 x 750 mm"):
        place_flat(developed_cylinder(1e9, 2000.0, 1200.0), small, T)
