"""Simulated scanner: noise, occlusion blobs, outliers, pose, files."""

from __future__ import annotations

import numpy as np
from matplotlib.path import Path as PolygonPath
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from mppf.core.errors import InputError
from mppf.geometry.read import read_points
from mppf.model.material import Material
from mppf.model.press import example_press_path, load_press
from mppf.sim.forming import PlateSample, form_plate
from mppf.sim.scanner import SimulatedScanner
from mppf.core.transform import apply_tf, invert_tf, rotation_angle_deg

THICKNESS_MM = 20.0


@pytest.fixture(scope="module")
def formed():
    press = load_press(example_press_path())
    px, py = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    mid = px**2 / (2 * 8000.0) - py**2 / (2 * 20000.0) + THICKNESS_MM / 2
    active = (np.abs(px) <= 1650) & (np.abs(py) <= 1150)
    outline = [[-1500.0, -1000.0], [1500.0, -1000.0], [1500.0, 1000.0], [-1500.0, 1000.0]]
    return form_plate(press, mid + THICKNESS_MM / 2, mid - THICKNESS_MM / 2, active,
                      PlateSample(THICKNESS_MM, Material()), outline)


def _normal_distance_to_top(formed, points_press):
    """Signed distance of press points from the top skin, along its normal (gentle plate)."""
    xy = points_press[:, :2]
    normal = formed.normals(xy)
    mid = formed.offset_points(xy, 0.0)
    return np.einsum("ij,ij->i", points_press - mid, normal) - formed.thickness_mm / 2


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_scan_statistics_are_as_specified(formed, seed):
    scanner = SimulatedScanner(noise_mm=0.3, occlusion_fraction=0.2, outlier_fraction=0.01, spacing_mm=20.0,
                               seed=seed)
    sample = scanner.sample(formed)
    n_total = len(sample.points) + len(sample.hidden_xy_mm)
    # the jitter carries some edge points past the plate's edge: those are not scanned
    n_grid = len(formed.sample_xy(20.0))
    assert 0.95 * n_grid < n_total <= n_grid
    assert PolygonPath(formed.outline_xy_mm).contains_points(sample.hidden_xy_mm).all()
    assert sample.occluded_fraction == pytest.approx(0.2, abs=0.005)
    assert sample.is_outlier.mean() == pytest.approx(0.01, abs=0.001)
    # back in press coordinates: noise about the top skin, outliers 5-50 mm off it
    press_pts = apply_tf(invert_tf(sample.tf_scan_press), sample.points)
    dist = _normal_distance_to_top(formed, press_pts)
    good = dist[~sample.is_outlier]
    assert np.std(good) == pytest.approx(0.3, rel=0.08)
    assert abs(np.mean(good)) < 0.03
    bad = np.abs(dist[sample.is_outlier])
    assert bad.min() > 4.0 and bad.max() < 51.0
    # the pose is arbitrary: a real turn and shift
    assert rotation_angle_deg(sample.tf_scan_press) > 1.0
    # occlusion: one or two contiguous blobs, not scattered points
    hidden = sample.hidden_xy_mm
    pairs = cKDTree(hidden).query_pairs(31.0, output_type="ndarray")  # grid neighbours + jitter
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(hidden),) * 2)
    n_parts, labels = connected_components(graph, directed=False)
    sizes = np.bincount(labels)
    assert sample.n_blobs in (1, 2)
    assert np.sort(sizes)[::-1][: sample.n_blobs].sum() >= 0.97 * len(hidden)


def test_scanner_is_seeded(formed):
    a = SimulatedScanner(seed=5).scan_points(formed)
    b = SimulatedScanner(seed=5).scan_points(formed)
    assert np.array_equal(a, b)
    scanner = SimulatedScanner(seed=5)
    first, second = scanner.scan_points(formed), scanner.scan_points(formed)
    assert np.array_equal(first, a)
    assert first.shape != second.shape or not np.allclose(first, second)


def test_noise_free_scan_lies_on_the_top_skin(formed):
    sample = SimulatedScanner(noise_mm=0.0, occlusion_fraction=0.0, outlier_fraction=0.0, seed=1).sample(formed)
    assert sample.occluded_fraction == 0.0 and sample.n_blobs == 0
    press_pts = apply_tf(invert_tf(sample.tf_scan_press), sample.points)
    assert np.max(np.abs(_normal_distance_to_top(formed, press_pts))) < 0.05


@pytest.mark.parametrize("suffix", [".ply", ".csv"])
def test_scan_writes_readable_files(formed, tmp_path, suffix):
    path = SimulatedScanner(seed=3).scan(formed, tmp_path / f"scan{suffix}")
    assert path.exists()
    cloud = read_points(path)
    expected = SimulatedScanner(seed=3).scan_points(formed)
    assert cloud.points.shape == expected.shape
    assert np.allclose(cloud.points, expected, atol=1e-9)


def test_bad_scanner_settings_are_refused():
    with pytest.raises(InputError, match="occlusion"):
        SimulatedScanner(occlusion_fraction=1.5)
    with pytest.raises(InputError, match="noise"):
        SimulatedScanner(noise_mm=-1.0)


def test_reference_mark_is_picked_in_the_scan_and_written_beside_it(formed, tmp_path):
    import json

    from mppf.measure.mark import MARK_SUFFIX
    from mppf.model.job_parts import reference_corner_xy

    corner = reference_corner_xy(formed.outline_xy_mm)
    sample = SimulatedScanner(seed=4).sample(formed, corner)
    # the mark is the top skin over the corner, in the scan's (arbitrary) pose, picked within a few mm
    truth = apply_tf(sample.tf_scan_press, formed.offset_points(corner[None], 0.5 * formed.thickness_mm))[0]
    assert 0.0 < np.linalg.norm(sample.mark_mm - truth) < 30.0
    # the scan itself is the same with or without the mark
    assert np.array_equal(sample.points, SimulatedScanner(seed=4).sample(formed).points)
    path = SimulatedScanner(seed=4).scan(formed, tmp_path / "scan.ply", corner)
    doc = json.loads((tmp_path / ("scan.ply" + MARK_SUFFIX)).read_text())
    assert np.allclose(doc["reference_mark_mm"], sample.mark_mm)
    assert read_points(path).points.shape == sample.points.shape
    assert not (tmp_path / ("plain.ply" + MARK_SUFFIX)).exists()
    SimulatedScanner(seed=4).scan(formed, tmp_path / "plain.ply")
    assert not (tmp_path / ("plain.ply" + MARK_SUFFIX)).exists()


def test_sample_grid_is_centred_on_the_plate(formed):
    """The rows and columns left over at the edges are the same on both sides (a grid from one
    edge would sample that edge and stop up to a spacing short of the other)."""
    for spacing in (20.0, 23.0, 37.0):
        xy = formed.sample_xy(spacing)
        lo, hi = formed.outline_xy_mm.min(axis=0), formed.outline_xy_mm.max(axis=0)
        np.testing.assert_allclose(xy.min(axis=0) - lo, hi - xy.max(axis=0), atol=1e-6)
        assert np.all(xy.min(axis=0) - lo < spacing)
