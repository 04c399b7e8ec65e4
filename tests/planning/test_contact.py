"""Ball-tip contact against closed-form geometry."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.planning.contact import PlacedSurface, tip_heights
from mppf.core.errors import InputError
from mppf.core.transform import make_tf
from plan_helpers import CylinderSurface, PlaneSurface, cylinder_tips_mm

R_TIP = 60.0
T = 20.0


def _rot_y(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


@pytest.mark.parametrize("theta_deg", [0.0, 3.0, -8.0, 15.0])
def test_tilted_plane_matches_closed_form(theta_deg):
    theta = np.radians(theta_deg)
    placed = PlacedSurface(PlaneSurface(), make_tf(_rot_y(theta), [10.0, -5.0, 40.0]))
    x = np.linspace(-600, 600, 9)
    y = np.linspace(-300, 300, 9)
    # mid-surface height on the axis: the plane through (10, -5, 40) with slope -tan(theta) in x
    z_mid = 40.0 - np.tan(theta) * (x - 10.0)
    big_r = R_TIP + T / 2
    up, lo = tip_heights(placed, x, y, tip_radius_mm=R_TIP, thickness_mm=T)
    np.testing.assert_allclose(up.tip_mm, z_mid + big_r / np.cos(theta) - R_TIP, atol=1e-6)
    np.testing.assert_allclose(lo.tip_mm, z_mid - big_r / np.cos(theta) + R_TIP, atol=1e-6)
    assert up.exact.all() and lo.exact.all()


def test_flat_plate_tips_are_zero_and_thickness():
    placed = PlacedSurface(PlaneSurface(), make_tf(translation=[0, 0, T / 2]))
    x, y = np.meshgrid(np.linspace(-1000, 1000, 5), np.linspace(-500, 500, 3))
    up, lo = tip_heights(placed, x.ravel(), y.ravel(), tip_radius_mm=R_TIP, thickness_mm=T)
    np.testing.assert_allclose(up.tip_mm, T, atol=1e-9)
    np.testing.assert_allclose(lo.tip_mm, 0.0, atol=1e-9)


@pytest.mark.parametrize("radius_mm", [800.0, 3000.0])
def test_cylinder_about_matrix_axis_matches_closed_form(radius_mm):
    lift = 7.5
    placed = PlacedSurface(CylinderSurface(radius_mm), make_tf(translation=[0, 0, lift]))
    y = np.linspace(-450, 450, 13)
    x = np.full_like(y, 225.0)
    up, lo = tip_heights(placed, x, y, tip_radius_mm=R_TIP, thickness_mm=T)
    exp_up, exp_lo = cylinder_tips_mm(y, radius_mm, R_TIP, T, lift_mm=lift)
    np.testing.assert_allclose(up.tip_mm, exp_up, atol=0.01)
    np.testing.assert_allclose(lo.tip_mm, exp_lo, atol=0.01)
    # the contact point lies on the mid-surface, on the line from the cylinder axis to the ball centre
    np.testing.assert_allclose(up.contact_mm[:, 1] / (radius_mm + lift - up.contact_mm[:, 2]),
                               y / np.sqrt((radius_mm - R_TIP - T / 2) ** 2 - y**2), rtol=1e-6)


def test_upside_down_frame_gives_the_same_tips():
    # the same valley cylinder, described in a local frame whose w axis points down
    flip = make_tf(np.diag([1.0, -1.0, -1.0]), [0, 0, 0])
    ridge = PlacedSurface(CylinderSurface(-2000.0), flip)
    valley = PlacedSurface(CylinderSurface(2000.0), np.eye(4))
    y = np.linspace(-400, 400, 7)
    x = np.zeros_like(y)
    for a, b in zip(tip_heights(ridge, x, y, tip_radius_mm=R_TIP, thickness_mm=T),
                    tip_heights(valley, x, y, tip_radius_mm=R_TIP, thickness_mm=T)):
        np.testing.assert_allclose(a.tip_mm, b.tip_mm, atol=1e-8)


def test_bad_thickness():
    placed = PlacedSurface(PlaneSurface(), np.eye(4))
    with pytest.raises(InputError, match="the plate thickness must be above 0 mm"):
        tip_heights(placed, [0.0], [0.0], tip_radius_mm=R_TIP, thickness_mm=0.0)
