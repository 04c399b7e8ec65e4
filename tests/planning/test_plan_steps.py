"""Multi-step split, validation, placement and springback over-bend, unit by unit."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import GeometryError, LimitError
from mppf.planning.job import StepStrokes
from mppf.planning.overbend import overbend
from mppf.planning.placement import minimax_offset, place_flat
from mppf.planning.press import example_press_path, load_press, press_from_dict
from mppf.forming.material import Material
from mppf.forming.springback import loaded_curvature
from mppf.core.grid import neighbour_differences
from mppf.planning.steps import split_steps, steps_needed, validate_steps
from plan_helpers import CylinderSurface, developed_cylinder

PRESS = load_press(example_press_path())
T = 20.0


def _flat_step(active=None):
    active = np.ones(PRESS.shape, bool) if active is None else active
    return StepStrokes(upper_mm=np.where(active, T, np.nan), lower_mm=np.where(active, 0.0, np.nan),
                       active=active)


def test_neighbour_differences_find_rows_and_columns():
    values = np.zeros((3, 4))
    values[1, 2] = 5.0
    active = np.ones((3, 4), bool)
    active[0, 2] = False
    (dx, ax, bx), (dy, ay, by) = neighbour_differences(values, active)
    # along x: (1,1)-(1,2) = +5 and (1,2)-(1,3) = -5
    pairs_x = {(tuple(a), tuple(b)): d for d, a, b in zip(dx, ax, bx) if d}
    assert pairs_x == {((1, 1), (1, 2)): 5.0, ((1, 2), (1, 3)): -5.0}
    # along y: (0,2) is inactive, so only (1,2)-(2,2) = -5
    pairs_y = {(tuple(a), tuple(b)): d for d, a, b in zip(dy, ay, by) if d}
    assert pairs_y == {((1, 2), (2, 2)): -5.0}


def test_split_steps_are_equal_fractions_and_steps_needed():
    active = np.ones(PRESS.shape, bool)
    upper = np.full(PRESS.shape, T)
    lower = np.zeros(PRESS.shape)
    upper[5, 5] += 70.0
    lower[5, 5] += 70.0
    n = steps_needed(upper, lower, active, PRESS, T)
    assert n == 3  # 70 mm neighbour difference, 30 mm per step
    steps = split_steps(upper, lower, active, T, n)
    np.testing.assert_allclose([s.lower_mm[5, 5] for s in steps], [70 / 3, 140 / 3, 70.0])
    report = validate_steps(steps, PRESS, T)
    assert report["max_neighbour_step_mm"] == pytest.approx(70 / 3)
    with pytest.raises(LimitError, match=r"step 1 upper\[5,5\]-upper\[5,6\].*dimpling"):
        validate_steps(split_steps(upper, lower, active, T, 2), PRESS, T)


def test_validation_lists_limit_gap_and_reversal_problems():
    bad = _flat_step()
    bad.upper_mm[2, 3] = 500.0
    with pytest.raises(LimitError, match=r"upper\[2,3\] stroke 500.00 mm outside -300..400"):
        validate_steps([bad], PRESS, T)
    squeezed = _flat_step()
    squeezed.upper_mm[4, 7] = T - 0.5
    with pytest.raises(LimitError, match=r"pair\[4,7\] tip gap 19.50 mm < thickness 20"):
        validate_steps([squeezed], PRESS, T)
    there = _flat_step()
    there.lower_mm[1, 1] = there.upper_mm[1, 1] = 10.0
    there.upper_mm[1, 1] = 30.0
    back = _flat_step()
    with pytest.raises(LimitError, match=r"step 2 pair\[1,1\] reverses direction"):
        validate_steps([there, back], PRESS, T)
    # inactive punches are not checked
    parked = _flat_step()
    parked.active[0, 0] = False
    parked.upper_mm[0, 0] = np.nan
    assert validate_steps([parked], PRESS, T)["passed"]


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


def test_overbend_turns_a_cylinder_into_the_loaded_cylinder():
    steel = Material(206000.0, 0.3, 235.0)
    radius = 5000.0
    bent = overbend(CylinderSurface(radius), T, steel, half_size_mm=900.0)
    k_loaded = float(loaded_curvature(1.0 / radius, T, steel))
    v = np.linspace(-800, 800, 9)
    u = np.full_like(v, 300.0)
    z, zu, zv, zuu, zuv, zvv = bent.derivatives(u, v)
    r_loaded = 1.0 / k_loaded
    np.testing.assert_allclose(z, r_loaded - np.sqrt(r_loaded**2 - v**2), atol=1e-9)
    np.testing.assert_allclose(zv, v / np.sqrt(r_loaded**2 - v**2), atol=1e-12)
    np.testing.assert_allclose(zvv, r_loaded**2 / (r_loaded**2 - v**2) ** 1.5, rtol=1e-9)
    np.testing.assert_allclose([zu, zuu, zuv], 0.0, atol=1e-15)


def test_overbend_refuses_a_radius_too_small_for_the_plate():
    steel = Material(206000.0, 0.3, 235.0)
    with pytest.raises(GeometryError, match="too small"):
        overbend(CylinderSurface(1200.0), T, steel, half_size_mm=1100.0)
