"""The plate's local frame (mppf.geometry.frame)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mppf.core.errors import GeometryError, InputError
from mppf.geometry.frame import LocalFrame, check_height_field, fit_frame
from mppf.geometry.read import read_points
from mppf.core.transform import apply_tf

OFFSET_MM = np.array([176000.0, 12500.0, 4200.0])


def plate_grid(shape="bowl", nu=31, nv=21, length_mm=3000.0, width_mm=2000.0, radius_mm=8000.0):
    """Local grid points (u, v, w) of a plate (bowl: concave seen from +w)."""
    u, v = np.meshgrid(np.linspace(-length_mm / 2, length_mm / 2, nu), np.linspace(-width_mm / 2, width_mm / 2, nv))
    u, v = u.ravel(), v.ravel()
    if shape == "bowl":
        w = (u**2 + v**2) / (2 * radius_mm)
    elif shape == "dome":
        w = -(u**2 + v**2) / (2 * radius_mm)
    else:
        w = np.zeros_like(u)
    return np.column_stack([u, v, w])


def test_frame_round_trip_and_transforms():
    rot = Rotation.from_euler("xyz", [20, -35, 110], degrees=True).as_matrix()
    frame = LocalFrame(origin=OFFSET_MM, axes=rot)
    pts = np.random.default_rng(0).normal(scale=1000.0, size=(100, 3)) + OFFSET_MM
    local = frame.to_local(pts)
    np.testing.assert_allclose(frame.to_world(local), pts, atol=1e-9)
    np.testing.assert_allclose(apply_tf(frame.tf_local_world, pts), local, atol=1e-9)
    np.testing.assert_allclose(apply_tf(frame.tf_world_local, local), pts, atol=1e-9)
    np.testing.assert_allclose(frame.tf_local_world @ frame.tf_world_local, np.eye(4), atol=1e-12)


def test_frame_rejects_non_orthonormal_or_left_handed_axes():
    with pytest.raises(InputError, match="orthonormal"):
        LocalFrame(origin=np.zeros(3), axes=np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(InputError, match="orthonormal"):
        LocalFrame(origin=np.zeros(3), axes=np.diag([1.0, 2.0, 1.0]))


@pytest.mark.parametrize("seed", range(5))
def test_fit_frame_recovers_a_moved_bowl(seed):
    rot = Rotation.random(random_state=seed).as_matrix()
    local = plate_grid("bowl")
    world = local @ rot + OFFSET_MM  # rows of rot are the true u, v, n axes
    frame = fit_frame(world)
    # u is the long side, n the normal; the bowl is concave seen from +n
    assert abs(frame.axes[0] @ rot[0]) == pytest.approx(1.0, abs=1e-9)
    np.testing.assert_allclose(frame.axes[2], rot[2], atol=1e-9)
    np.testing.assert_allclose(np.cross(frame.axes[0], frame.axes[1]), frame.axes[2], atol=1e-12)
    np.testing.assert_allclose(frame.origin, world.mean(axis=0), atol=1e-9)
    check_height_field(frame, world)


def test_dome_gets_the_opposite_normal():
    rot = Rotation.from_euler("zyx", [30, 40, 10], degrees=True).as_matrix()
    frame = fit_frame(plate_grid("dome") @ rot + OFFSET_MM)
    np.testing.assert_allclose(frame.axes[2], -rot[2], atol=1e-9)


def test_flat_plate_normal_points_up_and_u_along_long_side():
    rot = Rotation.from_euler("z", 30, degrees=True).as_matrix() @ Rotation.from_euler("x", 100, degrees=True).as_matrix()
    world = plate_grid("flat") @ rot.T + OFFSET_MM
    frame = fit_frame(world)
    assert frame.axes[2][2] >= 0.0
    u_true = rot[:, 0]
    assert abs(frame.axes[0] @ u_true) == pytest.approx(1.0, abs=1e-9)
    assert frame.axes[0][np.argmax(np.abs(frame.axes[0]))] > 0


def test_frame_does_not_depend_on_point_order():
    world = plate_grid("bowl") @ Rotation.random(random_state=3).as_matrix() + OFFSET_MM
    perm = np.random.default_rng(4).permutation(len(world))
    a, b = fit_frame(world), fit_frame(world[perm])
    np.testing.assert_allclose(a.axes, b.axes, atol=1e-9)
    np.testing.assert_allclose(a.origin, b.origin, atol=1e-6)


def test_fit_frame_collinear_points():
    t = np.linspace(0, 1000, 20)[:, None]
    with pytest.raises(GeometryError, match="plane"):
        fit_frame(OFFSET_MM + t * [1.0, 2.0, 3.0])


def test_fit_frame_too_few_points():
    with pytest.raises(GeometryError, match="at least 3"):
        fit_frame(OFFSET_MM + np.eye(3)[:2])


def test_hull_plates_are_height_fields_in_their_frame(hull_dir):
    files = sorted(hull_dir.glob("*.csv"))
    folded_in_hull_coordinates = 0
    for path in files:
        pts = read_points(path).points
        frame = fit_frame(pts)
        check_height_field(frame, pts)
        local = frame.to_local(pts)
        assert np.ptp(local[:, 0]) == pytest.approx(3000.0, rel=0.01)  # u = long side
        assert np.ptp(local[:, 2]) < 200.0  # depth from best plane
        try:
            check_height_field(LocalFrame(origin=np.zeros(3), axes=np.eye(3)), pts)
        except GeometryError:
            folded_in_hull_coordinates += 1
    assert folded_in_hull_coordinates >= 5  # most stand at 45 degrees or steeper in hull coordinates


def curled_plate(angle_deg=300.0, radius_mm=400.0, n_arc=80, n_len=15):
    """A cylinder arc curled past a half circle: folds over its best-fit plane."""
    theta, y = np.meshgrid(np.radians(np.linspace(0, angle_deg, n_arc)), np.linspace(0, 3000.0, n_len))
    theta, y = theta.ravel(), y.ravel()
    return np.column_stack([radius_mm * np.sin(theta), y, radius_mm * (1 - np.cos(theta))]) + OFFSET_MM


def test_folded_point_cloud_is_not_a_height_field():
    pts = curled_plate()
    with pytest.raises(GeometryError, match="folds over"):
        check_height_field(fit_frame(pts), pts)


def grid_faces(nu, nv):
    idx = np.arange(nu * nv).reshape(nv, nu)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    return np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])


def test_folded_mesh_is_not_a_height_field():
    pts = curled_plate(n_arc=40, n_len=10)
    faces = grid_faces(40, 10)
    with pytest.raises(GeometryError, match="triangles"):
        check_height_field(fit_frame(pts), pts, faces)


def test_good_mesh_is_a_height_field():
    pts = plate_grid("bowl", nu=31, nv=21) + OFFSET_MM
    check_height_field(fit_frame(pts), pts, grid_faces(31, 21))


def test_noisy_dense_scan_is_still_a_height_field():
    rng = np.random.default_rng(5)
    uv = rng.uniform([-1500, -1000], [1500, 1000], size=(20000, 2))
    w = (uv**2).sum(axis=1) / 16000.0 + rng.normal(scale=0.5, size=len(uv))
    pts = np.column_stack([uv, w]) @ Rotation.random(random_state=6).as_matrix() + OFFSET_MM
    check_height_field(fit_frame(pts), pts)


@pytest.mark.parametrize("offset_mm", [(5.0, 50.0), (30.0, 300.0)])
def test_scan_with_isolated_outliers_is_still_a_height_field(offset_mm):
    rng = np.random.default_rng(8)
    uv = rng.uniform([-1500, -1000], [1500, 1000], size=(30000, 2))
    w = (uv**2).sum(axis=1) / 16000.0 + rng.normal(scale=0.5, size=len(uv))
    outliers = rng.random(len(uv)) < 0.02
    w[outliers] += rng.choice([-1.0, 1.0], size=outliers.sum()) * rng.uniform(*offset_mm, size=outliers.sum())
    pts = np.column_stack([uv, w]) @ Rotation.random(random_state=9).as_matrix() + OFFSET_MM
    check_height_field(fit_frame(pts), pts)


def test_fold_is_found_despite_outliers():
    pts = curled_plate()
    rng = np.random.default_rng(10)
    noisy = pts + rng.normal(scale=0.5, size=pts.shape)
    noisy[rng.random(len(pts)) < 0.02] += [0.0, 0.0, 250.0]
    with pytest.raises(GeometryError, match="folds over"):
        check_height_field(fit_frame(noisy), noisy)
