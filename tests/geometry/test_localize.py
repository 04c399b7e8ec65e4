"""Foot points by damped Newton-Raphson (mppf.geometry.localize)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

from mppf.core.errors import InputError
from mppf.geometry.read import read_points
from mppf.geometry.localize import FootPoints, foot_points, project_vertical
from mppf.geometry.polynomial import fit_polynomial
from mppf.geometry.surface import fit_plate


@pytest.fixture(scope="module")
def saddle(hull_dir):
    """The real stern saddle plate P3 and its bicubic and spline surfaces."""
    pts = read_points(hull_dir / "P3_stern_saddle.csv").points
    return pts, fit_plate(pts, degree=3), fit_plate(pts, kind="spline")


def query_points(surface, n, offset_mm, seed):
    rng = np.random.default_rng(seed)
    (u0, u1), (v0, v1) = surface.bounds
    uv = rng.uniform([u0 + 50, v0 + 50], [u1 - 50, v1 - 50], size=(n, 2))
    w = surface.evaluate(uv[:, 0], uv[:, 1]) + rng.uniform(-offset_mm, offset_mm, size=n)
    return np.column_stack([uv, w])


def brute_force_foot(surface, p):
    """Dense grid search for the nearest surface point, refined by BFGS on |p - r|^2 / 2."""
    (u0, u1), (v0, v1) = surface.bounds
    gu, gv = np.meshgrid(np.linspace(u0 - 300, u1 + 300, 181), np.linspace(v0 - 300, v1 + 300, 121))
    gu, gv = gu.ravel(), gv.ravel()
    d2 = (gu - p[0]) ** 2 + (gv - p[1]) ** 2 + (surface.evaluate(gu, gv) - p[2]) ** 2
    start = np.array([gu[np.argmin(d2)], gv[np.argmin(d2)]])

    def fun(x):
        z, zu, zv, *_ = surface.derivatives(x[:1], x[1:])
        d = p - [x[0], x[1], z[0]]
        return 0.5 * d @ d, -np.array([d[0] + d[2] * zu[0], d[1] + d[2] * zv[0]])

    res = minimize(fun, start, jac=True, method="BFGS", options={"gtol": 1e-12, "maxiter": 500})
    return np.array([res.x[0], res.x[1], surface.evaluate(res.x[:1], res.x[1:])[0]])


@pytest.mark.parametrize("kind", ["poly", "spline"])
def test_newton_agrees_with_brute_force(saddle, kind):
    _, poly, spline = saddle
    surface = poly.surface if kind == "poly" else spline.surface
    pts = query_points(surface, 25, offset_mm=250.0, seed=3)
    feet = foot_points(surface, pts)
    assert isinstance(feet, FootPoints)
    assert feet.converged.all() and feet.n_failed == 0
    brute = np.array([brute_force_foot(surface, p) for p in pts])
    np.testing.assert_allclose(feet.xyz, brute, atol=1e-6)
    np.testing.assert_allclose(feet.uv, feet.xyz[:, :2])
    # the eq. (2.11) residual is at round-off and the distance is |p - r| with sign
    assert feet.residual_mm.max() < 1e-9
    np.testing.assert_allclose(np.abs(feet.distance_mm), np.linalg.norm(pts - feet.xyz, axis=1), atol=1e-9)


def test_distance_sign_follows_the_normal(saddle):
    _, plate, _ = saddle
    surface = plate.surface
    above = query_points(surface, 50, offset_mm=0.0, seed=4) + [0, 0, 30.0]
    below = above - [0, 0, 60.0]
    assert np.all(foot_points(surface, above).distance_mm > 29.0)
    assert np.all(foot_points(surface, below).distance_mm < -29.0)


def test_points_on_the_surface_are_their_own_foot_points(saddle):
    _, plate, _ = saddle
    on = query_points(plate.surface, 100, offset_mm=0.0, seed=5)
    feet = foot_points(plate.surface, on)
    np.testing.assert_allclose(feet.xyz, on, atol=1e-9)
    np.testing.assert_allclose(feet.distance_mm, 0.0, atol=1e-9)
    assert feet.iterations <= 2


def test_transform_is_applied_first(saddle):
    pts, plate, _ = saddle
    # the plate's own hull-coordinate points, mapped by tf_local_world into the surface frame
    feet_tf = foot_points(plate.surface, pts, tf=plate.frame.tf_local_world)
    feet_local = foot_points(plate.surface, plate.frame.to_local(pts))
    np.testing.assert_allclose(feet_tf.xyz, feet_local.xyz, atol=1e-9)
    # for a grid fitted with small residuals the normal distance is close to the vertical residual
    np.testing.assert_allclose(feet_tf.distance_mm, plate.residual_mm, atol=0.05)


def test_far_points_need_iterations_and_are_flagged_when_cut_short(saddle):
    _, plate, _ = saddle
    pts = query_points(plate.surface, 40, offset_mm=0.0, seed=6)
    pts[:, 2] += np.where(np.arange(40) % 2 == 0, 2000.0, 1.0)  # half far above, half close
    short = foot_points(plate.surface, pts, max_iterations=1)
    assert not short.converged[::2].any()
    full = foot_points(plate.surface, pts)
    assert full.converged.all()
    assert full.iterations > short.iterations


def test_point_beyond_the_centre_of_curvature_is_flagged():
    # paraboloid bowl, radius 1000 mm at the apex; a point on its axis above the centre
    # of curvature: the vertical start is a stationary point of the distance (a maximum),
    # not the foot point, and Newton cannot leave it by symmetry.
    g = np.linspace(-800.0, 800.0, 9)
    u, v = (a.ravel() for a in np.meshgrid(g, g))
    bowl = fit_polynomial(u, v, (u**2 + v**2) / 2000.0, degree=2)
    feet = foot_points(bowl, np.array([[0.0, 0.0, 1500.0], [0.0, 0.0, 500.0], [300.0, 100.0, 1500.0]]))
    assert feet.converged.tolist() == [False, True, True]
    # the off-axis point finds the true nearest point, which is not the vertical projection
    assert np.hypot(*feet.uv[2]) > 400.0


def test_project_vertical(saddle):
    _, plate, _ = saddle
    u, v = np.array([0.0, 100.0, -1400.0]), np.array([0.0, -200.0, 900.0])
    out = project_vertical(plate.surface, u, v)
    assert out.shape == (3, 3)
    np.testing.assert_array_equal(out[:, :2], np.column_stack([u, v]))
    np.testing.assert_allclose(out[:, 2], plate.surface.evaluate(u, v))


def test_bad_transform_shape(saddle):
    _, plate, _ = saddle
    with pytest.raises(InputError, match="4x4"):
        foot_points(plate.surface, np.zeros((3, 3)), tf=np.eye(3))


def test_bad_points_shape(saddle):
    _, plate, _ = saddle
    with pytest.raises(InputError, match=r"\(n, 3\)"):
        foot_points(plate.surface, np.zeros((3, 2)))
