"""Plate surfaces: polynomial and spline fits, derivatives, extension, curvature (mppf.geometry.surface)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mppf.core.errors import GeometryError, InputError
from mppf.geometry.io import read_points
from mppf.geometry.surface import (
    PolynomialSurface,
    SplineSurface,
    Surface,
    curvatures,
    fit_plate,
    fit_polynomial,
    fit_spline,
    principal_curvatures,
)

RNG = np.random.default_rng(11)
OFFSET_MM = np.array([176000.0, 12500.0, 4200.0])


def scattered_uv(n=600, length_mm=3000.0, width_mm=2000.0, seed=1):
    rng = np.random.default_rng(seed)
    return rng.uniform([-length_mm / 2, -width_mm / 2], [length_mm / 2, width_mm / 2], size=(n, 2)).T


def raw_poly(coef, u, v):
    """sum c_ij u^i v^j on raw (unscaled) mm coordinates, as a test oracle."""
    return sum(coef[i, j] * u**i * v**j for i in range(coef.shape[0]) for j in range(coef.shape[1]))


def known_bicubic():
    # terms sized to give a few 10 mm over a 3 x 2 m plate
    scale = np.array([[1.0, 1e-3, 1e-6, 1e-9]]).T * np.array([[1.0, 1e-3, 1e-6, 1e-9]])
    return RNG.uniform(-20.0, 20.0, size=(4, 4)) * scale


def test_exact_recovery_of_a_known_bicubic():
    coef = known_bicubic()
    u, v = scattered_uv()
    surf = fit_polynomial(u, v, raw_poly(coef, u, v), degree=3)
    assert isinstance(surf, PolynomialSurface) and isinstance(surf, Surface)
    assert surf.degree == 3 and surf.kind == "poly" and surf.coefficients.shape == (4, 4)
    assert surf.rms_mm < 1e-9 and surf.max_abs_mm < 1e-8
    ut, vt = scattered_uv(200, seed=2)
    np.testing.assert_allclose(surf.evaluate(ut, vt), raw_poly(coef, ut, vt), atol=1e-8)


def test_conditioning_with_full_scale_hull_coordinates():
    # raw u^3 v^3 would be ~1e29 here: the fit must centre and scale
    coef = known_bicubic()
    u, v = scattered_uv()
    z = raw_poly(coef, u, v)
    surf = fit_polynomial(u + OFFSET_MM[0], v + OFFSET_MM[1], z, degree=3)
    assert surf.rms_mm < 1e-7
    np.testing.assert_allclose(surf.evaluate(u + OFFSET_MM[0], v + OFFSET_MM[1]), z, atol=1e-7)
    np.testing.assert_allclose(surf.center_mm, OFFSET_MM[:2], atol=5.0)


def test_degree_four_fit_at_hull_offsets_via_fit_plate():
    # a paraboloid bowl moved far away and rotated: frame, fit and residual at 1e-6 mm
    u, v = scattered_uv(900)
    local = np.column_stack([u, v, (u**2 / 9000.0 + v**2 / 5000.0) / 2])
    rot = Rotation.from_euler("xyz", [35, -20, 70], degrees=True).as_matrix()
    plate = fit_plate(local @ rot + OFFSET_MM, degree=4)
    assert plate.degree == 4 and plate.kind == "poly"
    assert plate.rms_mm < 1e-6 and plate.max_abs_mm < 1e-5
    assert plate.residual_mm.shape == (900,) and plate.n_points == 900


def test_derivatives_match_finite_differences_polynomial():
    coef = known_bicubic()
    u, v = scattered_uv()
    surf = fit_polynomial(u, v, raw_poly(coef, u, v), degree=3)
    check_derivatives(surf, *scattered_uv(50, seed=4))


def check_derivatives(surf, u, v, h=1e-2):
    z, zu, zv, zuu, zuv, zvv = surf.derivatives(u, v)
    np.testing.assert_allclose(z, surf.evaluate(u, v), atol=1e-12)
    d = lambda du, dv: surf.derivatives(u + du, v + dv)  # noqa: E731
    tol = dict(rtol=1e-5, atol=1e-8)
    np.testing.assert_allclose(zu, (d(h, 0)[0] - d(-h, 0)[0]) / (2 * h), **tol)
    np.testing.assert_allclose(zv, (d(0, h)[0] - d(0, -h)[0]) / (2 * h), **tol)
    np.testing.assert_allclose(zuu, (d(h, 0)[1] - d(-h, 0)[1]) / (2 * h), **tol)
    np.testing.assert_allclose(zuv, (d(0, h)[1] - d(0, -h)[1]) / (2 * h), **tol)
    np.testing.assert_allclose(zvv, (d(0, h)[2] - d(0, -h)[2]) / (2 * h), **tol)


def test_normals_are_unit_and_orthogonal_to_tangents():
    coef = known_bicubic()
    u, v = scattered_uv()
    surf = fit_polynomial(u, v, raw_poly(coef, u, v), degree=3)
    _, zu, zv, *_ = surf.derivatives(u, v)
    n = surf.normals(u, v)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    assert np.all(n[:, 2] > 0)
    np.testing.assert_allclose(n[:, 0] + n[:, 2] * zu, 0.0, atol=1e-12)  # . (1, 0, zu)
    np.testing.assert_allclose(n[:, 1] + n[:, 2] * zv, 0.0, atol=1e-12)  # . (0, 1, zv)


def test_evaluate_keeps_grid_shapes():
    u, v = scattered_uv()
    surf = fit_polynomial(u, v, u * v / 1e4, degree=2)
    gu, gv = np.meshgrid(np.linspace(-100, 100, 5), np.linspace(-50, 50, 4))
    assert surf.evaluate(gu, gv).shape == (4, 5)
    assert all(d.shape == (4, 5) for d in surf.derivatives(gu, gv))
    assert surf.normals(gu, gv).shape == (4, 5, 3)


@pytest.mark.parametrize("true_degree", [2, 3, 4])
def test_auto_degree_picks_the_generating_degree(true_degree):
    u, v = scattered_uv(1500)
    s, t = u / 1500.0, v / 1000.0
    z = 30 * s**2 + 20 * t**2 - 10 * s * t
    if true_degree >= 3:
        z = z + 25 * s**3 - 15 * s * t**2 + 12 * s**3 * t**3
    if true_degree == 4:
        z = z + 30 * s**4 * t**2 - 25 * t**4 + 20 * s**4 * t**4
    z = z + np.random.default_rng(5).normal(scale=0.05, size=z.shape)
    surf = fit_polynomial(u, v, z, degree="auto")
    assert surf.degree == true_degree
    assert [k for k, _ in surf.heldout_rms_mm] == [2, 3, 4]
    again = fit_polynomial(u, v, z, degree="auto")
    assert again.heldout_rms_mm == surf.heldout_rms_mm  # deterministic split


def knuckle_plate(n=2500):
    u, v = scattered_uv(n, seed=8)
    return u, v, 40.0 * np.tanh(u / 300.0) + v**2 / 20000.0


def test_spline_beats_polynomial_where_one_polynomial_does_not_hold():
    u, v, z = knuckle_plate()
    poly = fit_polynomial(u, v, z, degree=4)
    spline = fit_spline(u, v, z)
    assert isinstance(spline, SplineSurface) and isinstance(spline, Surface)
    assert spline.kind == "spline" and spline.degree == 3
    assert poly.rms_mm > 1.0
    assert spline.rms_mm < poly.rms_mm / 5
    assert spline.max_abs_mm < poly.max_abs_mm / 5


def test_spline_pieces_equal_the_scipy_spline_inside():
    u, v, z = knuckle_plate()
    spline = fit_spline(u, v, z)
    uq, vq = scattered_uv(300, length_mm=2990, width_mm=1990, seed=12)
    ours = spline.derivatives(uq, vq)
    for value, (du, dv) in zip(ours, [(0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2)]):
        ref = spline.spline.ev(uq, vq, dx=du, dy=dv)
        np.testing.assert_allclose(value, ref, rtol=1e-9, atol=1e-10 * np.abs(ref).max())


def test_spline_derivatives_inside_and_outside_bounds():
    u, v, z = knuckle_plate()
    spline = fit_spline(u, v, z)
    (umin, umax), (vmin, vmax) = spline.bounds
    inside_u, inside_v = scattered_uv(40, length_mm=2800, width_mm=1800, seed=9)
    check_derivatives(spline, inside_u, inside_v, h=1e-3)
    # beyond one edge (u) and beyond a corner, by up to 100 mm (away from the kinks at the edge lines)
    check_derivatives(spline, np.full(10, umax + 60.0), np.linspace(vmin + 50, vmax - 50, 10), h=1e-3)
    check_derivatives(spline, np.linspace(umin + 50, umax - 50, 10), np.full(10, vmin - 80.0), h=1e-3)
    check_derivatives(spline, np.full(3, umin - 70.0), np.full(3, vmax + 90.0), h=1e-3)


def test_spline_extension_is_continuous_and_first_order():
    u, v, z = knuckle_plate()
    spline = fit_spline(u, v, z)
    (_, umax), _ = spline.bounds
    vs = np.linspace(-900, 900, 7)
    edge_z, edge_zu = spline.derivatives(np.full(7, umax), vs)[:2]
    eps = 1e-6
    np.testing.assert_allclose(spline.evaluate(np.full(7, umax + eps), vs), edge_z, atol=1e-5)
    np.testing.assert_allclose(spline.derivatives(np.full(7, umax + eps), vs)[1], edge_zu, atol=1e-7)
    np.testing.assert_allclose(spline.evaluate(np.full(7, umax + 100.0), vs), edge_z + 100.0 * edge_zu, atol=1e-9)


def test_polynomial_extends_smoothly_outside_bounds():
    coef = known_bicubic()
    u, v = scattered_uv()
    surf = fit_polynomial(u, v, raw_poly(coef, u, v), degree=3)
    far_u, far_v = np.array([1600.0, -1620.0]), np.array([1100.0, -1090.0])
    np.testing.assert_allclose(surf.evaluate(far_u, far_v), raw_poly(coef, far_u, far_v), atol=1e-7)


def test_spline_bridges_a_hole_in_the_scan():
    # no data in the middle: the knot grid coarsens instead of inventing a shape there
    u, v = scattered_uv(3000, seed=13)
    z = u**2 / 8000.0 + 30.0 * np.sin(u / 300.0) + np.random.default_rng(2).normal(scale=0.5, size=u.shape)
    keep = (np.abs(u) > 700) | (np.abs(v) > 500)
    spline = fit_spline(u[keep], v[keep], z[keep])
    g = np.linspace(-600.0, 600.0, 7)
    np.testing.assert_allclose(spline.evaluate(g, np.zeros(7)), g**2 / 8000.0 + 30.0 * np.sin(g / 300.0), atol=2.0)


def test_spline_smoothing_targets_the_rms():
    u, v, z = knuckle_plate()
    noisy = z + np.random.default_rng(3).normal(scale=0.5, size=z.shape)
    spline = fit_spline(u, v, noisy, smoothing=0.8)
    assert spline.smoothing == 0.8
    assert spline.rms_mm == pytest.approx(0.8, rel=0.05)


def test_spline_smoothing_must_be_positive():
    u, v, z = knuckle_plate(100)
    with pytest.raises(InputError, match="smoothing"):
        fit_spline(u, v, z, smoothing=-1.0)


def test_fit_with_too_few_points_for_degree():
    u, v = scattered_uv(20)
    with pytest.raises(GeometryError, match="at least 25"):
        fit_polynomial(u, v, u * 0, degree=4)


def test_points_on_few_lines_do_not_determine_the_surface():
    u = np.repeat([-1000.0, 0.0, 1000.0], 20)  # three columns of points: rank deficient in u^3
    v = np.tile(np.linspace(-900, 900, 20), 3)
    with pytest.raises(GeometryError, match="rank"):
        fit_polynomial(u, v, u + v, degree=3)


def test_unknown_degree():
    u, v = scattered_uv(50)
    with pytest.raises(InputError, match="degree"):
        fit_polynomial(u, v, u, degree=5)


def test_mismatched_arrays():
    with pytest.raises(InputError, match="one length"):
        fit_polynomial(np.zeros(20), np.zeros(19), np.zeros(20))


# ----------------------------------------------------------------- fit_plate on bad and real plates


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


# ----------------------------------------------------------------- curvature


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
