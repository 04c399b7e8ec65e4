"""Curvatures of plate surfaces (mppf.geometry.curvature)."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.geometry.curvature import curvatures, principal_curvatures
from mppf.geometry.polynomial import fit_polynomial
from mppf.geometry.read import read_points
from mppf.geometry.surface import fit_plate
from surface_helpers import scattered_uv


class Cylinder:
    """Exact z = R - sqrt(R^2 - u^2): curvature 1/R across u, 0 along v."""

    kind, degree, rms_mm, max_abs_mm = "exact", 0, 0.0, 0.0
    bounds = ((-1000.0, 1000.0), (-1000.0, 1000.0))

    def __init__(self, radius_mm):
        self.r = radius_mm

    def derivatives(self, u, v):
        u = np.asarray(u, dtype=float)
        root = np.sqrt(self.r**2 - u**2)
        zero = np.zeros_like(u)
        return self.r - root, u / root, zero, self.r**2 / root**3, zero, zero


def test_cylinder_curvatures_away_from_the_apex():
    u = np.array([0.0, 300.0, -700.0, 900.0])
    c = curvatures(Cylinder(2000.0), u, np.zeros(4))
    np.testing.assert_allclose(c.k1, 1 / 2000.0, rtol=1e-12)
    np.testing.assert_allclose(c.k2, 0.0, atol=1e-15)
    np.testing.assert_allclose(np.abs(c.dir1), [[1.0, 0.0]] * 4, atol=1e-12)
    np.testing.assert_allclose(np.abs(c.dir2), [[0.0, 1.0]] * 4, atol=1e-12)
    np.testing.assert_allclose(c.gaussian, 0.0, atol=1e-18)
    np.testing.assert_allclose(c.mean, 1 / 4000.0, rtol=1e-12)


def test_saddle_curvatures_and_directions_from_a_fitted_surface():
    u, v = scattered_uv(400)
    radius = 8000.0
    # saddle rotated by 30 degrees in the plane: principal directions at +-30 degrees
    a = np.radians(30.0)
    p, q = np.cos(a) * u + np.sin(a) * v, -np.sin(a) * u + np.cos(a) * v
    surf = fit_polynomial(u, v, (p**2 - q**2) / (2 * radius), degree=2)
    k1, k2, dir1 = principal_curvatures(surf, np.zeros(1), np.zeros(1))
    np.testing.assert_allclose([k1[0], k2[0]], [1 / radius, -1 / radius], rtol=1e-9)
    np.testing.assert_allclose(np.abs(dir1[0] @ [np.cos(a), np.sin(a)]), 1.0, atol=1e-9)
    c = curvatures(surf, np.zeros(1), np.zeros(1))
    np.testing.assert_allclose(c.gaussian, -1 / radius**2, rtol=1e-9)
    np.testing.assert_allclose(c.mean, 0.0, atol=1e-15)


def test_hull_bilge_radius(hull_dir):
    # P1 smooth: a midbody bilge of radius about 4.7 m (README), flat along the ship
    plate = fit_plate(read_points(hull_dir / "P1_midbody_bilge_smooth.csv").points, degree=3)
    k1, k2, _ = principal_curvatures(plate.surface, np.zeros(1), np.zeros(1))
    assert 1 / k1[0] == pytest.approx(4700.0, rel=0.05)
    assert abs(k2[0]) < 1 / 100000.0
