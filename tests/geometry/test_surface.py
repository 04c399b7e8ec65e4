"""The one-call plate fit: frame, height-field check, surface, residual (mppf.geometry.surface)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mppf.core.errors import GeometryError, InputError
from mppf.geometry.read import read_points
from mppf.geometry.surface import fit_plate
from surface_helpers import OFFSET_MM, scattered_uv


def test_degree_four_fit_at_hull_offsets_via_fit_plate():
    # a paraboloid bowl moved far away and rotated: frame, fit and residual at 1e-6 mm
    u, v = scattered_uv(900)
    local = np.column_stack([u, v, (u**2 / 9000.0 + v**2 / 5000.0) / 2])
    rot = Rotation.from_euler("xyz", [35, -20, 70], degrees=True).as_matrix()
    plate = fit_plate(local @ rot + OFFSET_MM, degree=4)
    assert plate.degree == 4 and plate.kind == "poly"
    assert plate.rms_mm < 1e-6 and plate.max_abs_mm < 1e-5
    assert plate.residual_mm.shape == (900,) and plate.n_points == 900


def test_fit_plate_unknown_kind():
    with pytest.raises(InputError, match="kind"):
        fit_plate(np.random.default_rng(0).normal(size=(50, 3)), kind="nurbs")


def test_fit_plate_smoothing_only_for_splines():
    with pytest.raises(InputError, match="smoothing"):
        fit_plate(np.random.default_rng(0).normal(size=(50, 3)), kind="poly", smoothing=1.0)


def test_fit_plate_too_few_points():
    with pytest.raises(GeometryError, match="at least 16"):
        fit_plate(np.random.default_rng(0).normal(size=(10, 3)), degree=3)


def test_fit_plate_collinear():
    t = np.linspace(0, 3000, 50)[:, None]
    with pytest.raises(GeometryError, match="collinear"):
        fit_plate(OFFSET_MM + t * [1.0, 0.2, 0.1])


def test_fit_plate_refuses_a_folded_plate():
    theta, y = np.meshgrid(np.radians(np.linspace(0, 300, 60)), np.linspace(0, 3000, 12))
    pts = np.column_stack([400 * np.sin(theta.ravel()), y.ravel(), 400 * (1 - np.cos(theta.ravel()))])
    with pytest.raises(GeometryError, match="folds over"):
        fit_plate(pts + OFFSET_MM)


def test_each_hull_plate_fits_as_a_height_field(hull_dir):
    for path in sorted(hull_dir.glob("*.csv")):
        pts = read_points(path).points
        poly = fit_plate(pts, degree=3, source=path.name)
        spline = fit_plate(pts, kind="spline", source=path.name)
        np.testing.assert_allclose(np.sqrt(np.mean(poly.residual_mm**2)), poly.rms_mm)
        assert poly.max_abs_mm == pytest.approx(np.abs(poly.residual_mm).max())
        # facet kinks of the coarse hull meshes stay below ~10 mm; the smoothed grids are bicubic
        limit = 0.05 if "smooth" in path.name else 2.0
        assert poly.rms_mm < limit, path.name
        assert spline.rms_mm <= poly.rms_mm + 1e-6, path.name
        # the frame makes it a shallow height field: depth below 200 mm over a 3 m plate
        local = poly.frame.to_local(pts)
        np.testing.assert_allclose(local[:, 2] - poly.residual_mm, poly.surface.evaluate(local[:, 0], local[:, 1]))
