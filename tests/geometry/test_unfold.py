"""Tests of mppf.geometry.unfold: developable plates unfold exactly, doubly curved ones with the
strain the analytic estimate predicts, never as a mirror image."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.distance import pdist
from scipy.spatial.transform import Rotation

from mppf.core.errors import GeometryError, InputError
from mppf.geometry.read import read_points
from mppf.geometry.unfold import unfold


HULL = Path(__file__).resolve().parents[2] / "mppf" / "examples" / "hull"


def _to_hull(points, seed=3):
    """Put a plate built in its own coordinates somewhere in 'hull coordinates'."""
    rot = Rotation.random(random_state=seed).as_matrix()
    return points @ rot.T + np.array([176000.0, -24000.0, 2100.0])


def _procrustes(source, target):
    """Best rigid 2D fit of source onto target allowing reflection: (det, rms residual)."""
    s, t = source - source.mean(axis=0), target - target.mean(axis=0)
    u, _, vt = np.linalg.svd(s.T @ t)
    rot = (u @ vt).T
    residual = s @ rot.T - t
    return float(np.linalg.det(rot)), float(np.sqrt(np.mean(np.sum(residual ** 2, axis=1))))


def _cylinder(radius_mm, angle_rad, length_mm, n_arc=61, n_axis=41):
    """Cylinder patch (grid) and its true development (arc length, axial)."""
    theta, y = np.meshgrid(np.linspace(-angle_rad / 2, angle_rad / 2, n_arc),
                           np.linspace(0.0, length_mm, n_axis), indexing="ij")
    points = np.column_stack([radius_mm * np.sin(theta).ravel(), y.ravel(),
                              radius_mm * (1 - np.cos(theta)).ravel()])
    development = np.column_stack([radius_mm * theta.ravel(), y.ravel()])
    return points, development


def test_cylinder_unfolds_to_rectangle_of_width_r_phi():
    radius, angle, length = 4000.0, 0.75, 2000.0
    points, development = _cylinder(radius, angle, length)
    result = unfold(_to_hull(points))
    width, height = np.ptp(result.flat[:, 0]), np.ptp(result.flat[:, 1])
    assert abs(width - radius * angle) / (radius * angle) < 1e-4
    assert abs(height - length) / length < 1e-4
    # every point lands where the development puts it (same order), up to a rigid motion
    det, rms = _procrustes(result.flat[:, :2], development)
    assert det > 0 and rms < 0.05
    assert result.max_strain_pct < 1e-6 and result.developable
    assert abs(result.area_change_pct) < 1e-6 and abs(result.outline_length_change_pct) < 1e-6
    assert result.warnings == ()


def test_flat_plate_lies_at_z0_centred_long_side_on_x():
    radius, angle, length = 3000.0, 0.6, 2600.0  # developed 1800 x 2600: long side is the axis
    points, _ = _cylinder(radius, angle, length)
    flat = unfold(_to_hull(points, seed=8)).flat
    assert np.all(flat[:, 2] == 0.0)
    lo, hi = flat[:, :2].min(axis=0), flat[:, :2].max(axis=0)
    np.testing.assert_allclose(lo + hi, 0.0, atol=1e-6)
    assert hi[0] - lo[0] == pytest.approx(length, rel=1e-4)
    assert hi[1] - lo[1] == pytest.approx(radius * angle, rel=1e-4)


def test_cone_unfolds_to_its_annular_sector():
    half_angle, s_in, s_out, turn = 0.35, 6000.0, 8200.0, 1.3
    s, t = np.meshgrid(np.linspace(s_in, s_out, 41), np.linspace(0.0, turn, 61), indexing="ij")
    cone = np.column_stack([(s * np.sin(half_angle) * np.cos(t)).ravel(),
                            (s * np.sin(half_angle) * np.sin(t)).ravel(),
                            (s * np.cos(half_angle)).ravel()])
    result = unfold(_to_hull(cone, seed=5))
    sector = turn * np.sin(half_angle)  # angle of the developed sector
    development = np.column_stack([(s * np.cos(t * np.sin(half_angle))).ravel(),
                                   (s * np.sin(t * np.sin(half_angle))).ravel()])
    det, rms = _procrustes(result.flat[:, :2], development)
    assert det > 0 and rms < 0.1
    # radii: the apex is where the straight generators meet; arcs: outer and inner edges
    flat = result.flat[:, :2].reshape(s.shape + (2,))
    d_in, d_out = flat[0, 0] - flat[0, -1], flat[-1, 0] - flat[-1, -1]
    apex = _meet(flat[0, 0], flat[-1, 0], flat[0, -1], flat[-1, -1])
    assert np.linalg.norm(flat[0, 0] - apex) == pytest.approx(s_in, rel=1e-5)
    assert np.linalg.norm(flat[-1, -1] - apex) == pytest.approx(s_out, rel=1e-5)
    arc_out = np.sum(np.linalg.norm(np.diff(flat[-1], axis=0), axis=1))
    arc_in = np.sum(np.linalg.norm(np.diff(flat[0], axis=0), axis=1))
    assert arc_out == pytest.approx(s_out * sector, rel=1e-4)
    assert arc_in == pytest.approx(s_in * sector, rel=1e-4)
    assert np.linalg.norm(d_out) / np.linalg.norm(d_in) == pytest.approx(s_out / s_in, rel=1e-5)
    assert result.max_strain_pct < 1e-6


def _meet(a0, a1, b0, b1):
    """Intersection of the lines a0-a1 and b0-b1 in the plane."""
    m = np.column_stack([a1 - a0, b0 - b1])
    k = np.linalg.solve(m, b0 - a0)
    return a0 + k[0] * (a1 - a0)


def _polar_cap(sphere_radius_mm, cap_radius_mm, spacing_mm=50.0):
    """Spherical cap sampled on rings (geodesic radii), nearly uniform spacing."""
    rings = [np.zeros((1, 2))]
    for k in range(1, int(cap_radius_mm / spacing_mm) + 1):
        s = k * spacing_mm
        count = int(round(2 * np.pi * s / spacing_mm))
        angle = np.arange(count) * 2 * np.pi / count + 0.3 * k
        rings.append(np.column_stack([s * np.cos(angle), s * np.sin(angle)]))
    polar = np.concatenate(rings)
    s = np.hypot(polar[:, 0], polar[:, 1])
    direction = polar / np.maximum(s, 1e-12)[:, None]
    r = sphere_radius_mm * np.sin(s / sphere_radius_mm)
    points = np.column_stack([direction * r[:, None], sphere_radius_mm * (1 - np.cos(s / sphere_radius_mm))])
    return points, s


@pytest.mark.parametrize("sphere_radius_mm", [20000.0, 5000.0])
def test_sphere_cap_strain_matches_analytic_estimate(sphere_radius_mm):
    # Least-squares flattening of a cap of radius a on a sphere of radius R: the rim is
    # stretched along the circumference by a^2 / (8 R^2), the centre compressed by about
    # half of that (docs/unfold.md).
    a = 1500.0
    points, s = _polar_cap(sphere_radius_mm, a)
    result = unfold(_to_hull(points))
    estimate_pct = 100.0 * a * a / (8 * sphere_radius_mm ** 2)
    rim = s > a - 1.0
    assert result.strain_pct[rim].mean() == pytest.approx(estimate_pct, rel=0.1)
    assert 0.9 * estimate_pct < result.max_strain_pct < 1.4 * estimate_pct
    assert 0.3 * estimate_pct < result.strain_pct[s < 200].mean() < 0.7 * estimate_pct
    # the rim is stretched along the circumference: the larger principal strain is positive
    rim_faces = np.all(rim[result.faces], axis=1) | (np.sum(rim[result.faces], axis=1) == 2)
    assert np.all(result.triangle_strain_pct[rim_faces, 1] > 0)


def test_strain_over_limit_warns_and_names_the_region():
    points, _ = _polar_cap(3000.0, 1500.0, spacing_mm=100.0)
    result = unfold(points)
    assert result.max_strain_pct > 1.5
    assert len(result.warnings) == 1
    message = result.warnings[0]
    assert "exceeds the limit 1.5 %" in message and result.worst_region in message
    assert f"point {result.worst_point}" in message
    u_m = f"u={result.worst_uv_mm[0] / 1000:+.2f} m"
    assert u_m in message
    assert unfold(points, strain_limit_pct=20.0).warnings == ()
    assert not result.developable


def test_flat_input_comes_back_unchanged_up_to_rigid_motion():
    rng = np.random.default_rng(4)
    uv = rng.uniform([-1400, -900], [1400, 900], size=(600, 2))
    uv = uv[(uv[:, 0] < 600) | (uv[:, 1] < 200)]  # an L-shaped, non-convex outline
    points = _to_hull(np.column_stack([uv, np.zeros(len(uv))]), seed=11)
    result = unfold(points)
    np.testing.assert_allclose(pdist(result.flat), pdist(points), rtol=1e-9, atol=1e-6)
    assert _procrustes(result.flat[:, :2], result.frame.to_local(points)[:, :2])[0] > 0  # not mirrored
    assert result.max_strain_pct < 1e-6
    assert len(result.flat) == len(points)


@pytest.mark.parametrize("radius_mm", [3500.0, 40000.0])  # conformal start / projection start
def test_no_mirror_image_on_an_asymmetric_plate(radius_mm):
    # A curved, asymmetric plate (a cylinder patch with a cut-off corner), concave seen
    # from +z: seen from its +n side it must come out turned, never mirrored.
    points, development = _cylinder(radius_mm, 2800.0 / radius_mm, 2000.0)
    keep = development[:, 1] < 1500.0 + 0.5 * development[:, 0]
    for seed in (1, 2):
        design = _to_hull(points[keep], seed=seed)
        result = unfold(design)
        det, rms = _procrustes(result.flat[:, :2], development[keep])
        assert det > 0 and rms < 0.05
        # the frame's +n view of the design and the flat plate turn the same way
        uv = result.frame.to_local(design)[:, :2]
        assert _procrustes(result.flat[:, :2], uv)[0] > 0
        # and +n points to the concave side: the design's own +z here
        assert result.frame.axes[2] @ Rotation.random(random_state=seed).as_matrix()[:, 2] > 0.99


def test_mesh_faces_are_used_whatever_their_winding():
    points, development = _cylinder(4000.0, 0.75, 2000.0, n_arc=31, n_axis=21)
    grid = np.arange(31 * 21).reshape(31, 21)
    a, b, c, d = grid[:-1, :-1].ravel(), grid[1:, :-1].ravel(), grid[1:, 1:].ravel(), grid[:-1, 1:].ravel()
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    design = _to_hull(points)
    for tri in (faces, faces[:, ::-1]):
        result = unfold(design, tri)
        assert result.faces.shape == faces.shape
        det, rms = _procrustes(result.flat[:, :2], development)
        assert det > 0 and rms < 0.1


@pytest.mark.parametrize("name", sorted(p.name for p in HULL.glob("*.csv")))
def test_real_hull_patches_unfold(name):
    design = read_points(HULL / name).points
    result = unfold(design)
    assert result.flat.shape == design.shape
    assert result.max_strain_pct < 0.1  # all six plates are mild enough for the press
    if name.startswith(("P1", "K1")):  # single curvature: nearly developable
        assert result.developable
        assert result.rms_strain_pct < 0.02
    assert abs(result.area_change_pct) < 0.01
    assert abs(result.outline_length_change_pct) < 0.05
    # laid out at 50 mm in the tangent plane: the development is a bit larger than 3.0 x 2.0 m
    width, height = np.ptp(result.flat[:, :2], axis=0)
    assert 3000.0 <= width < 3050.0 and 2000.0 <= height < 2050.0
    # neighbouring grid points stay about 50 mm apart
    grid = result.flat[:, :2].reshape(61, 41, 2)
    steps = np.linalg.norm(np.diff(grid, axis=0), axis=2)
    assert 45.0 < steps.min() and steps.max() < 56.0
    assert result.warnings == ()


def test_too_few_or_collinear_points_are_refused():
    with pytest.raises(GeometryError, match="2 point"):
        unfold([[0, 0, 0], [1, 0, 0]])
    with pytest.raises(GeometryError, match="collinear"):
        unfold([[0, 0, 0], [1, 1, 1], [2, 2, 2], [3, 3, 3]])


def test_plate_folding_over_in_its_own_frame_is_refused():
    # an S-shaped sheet whose upper layer overhangs the lower one
    t, y = np.meshgrid(np.linspace(0, 1.5 * np.pi, 60), np.linspace(0, 2000, 20), indexing="ij")
    x = 800 * np.sin(t) + 200 * t
    z = -800 * np.cos(t)
    with pytest.raises(GeometryError, match="folds over"):
        unfold(np.column_stack([x.ravel(), y.ravel(), z.ravel()]))


def test_bad_faces_and_limits_are_refused():
    points, _ = _cylinder(4000.0, 0.5, 1000.0, n_arc=5, n_axis=4)
    with pytest.raises(InputError, match="shape"):
        unfold(points, faces=[[0, 1]])
    with pytest.raises(InputError, match="refer to point 99"):
        unfold(points, faces=[[0, 1, 99]])
    with pytest.raises(GeometryError, match="belong to no triangle"):
        unfold(points, faces=[[0, 1, 4]])
    with pytest.raises(InputError, match="strain limit"):
        unfold(points, strain_limit_pct=-1.0)


def test_non_convex_outline_is_not_bridged_by_slivers():
    # an L-shaped cylinder grid given as points: Delaunay fills the notch, the peeling
    # must take those triangles off again (a small chamfer at the inner corner may stay)
    points, development = _cylinder(4000.0, 0.75, 2000.0)
    i, j = np.meshgrid(np.arange(61), np.arange(41), indexing="ij")
    keep = ~((i.ravel() > 30) & (j.ravel() > 20))
    result = unfold(_to_hull(points[keep]))
    cells = 60 * 40 - 30 * 20
    assert 2 * cells <= len(result.faces) <= 2 * cells + 6
    sides = result.flat[result.faces] - np.roll(result.flat[result.faces], 1, axis=1)
    assert np.linalg.norm(sides, axis=2).max() < 2.4 * 50.0  # the chamfer: sqrt(5) x 50 mm
    det, rms = _procrustes(result.flat[:, :2], development[keep])
    assert det > 0 and rms < 0.05
    assert result.max_strain_pct < 0.01
