"""A plate cut from a hull model (mppf.geometry.extract): regions, girth, the KCS patches.

The KCS patches K1 and K3 (cut from ship_kcs.igs, scaled by 31.6) are cut again from the IGES
by their region and must come out as the same plate; a girth plate is checked on a box-bilge
hull written by gmsh (its stations: ``tests/geometry/test_stations.py``); the second public hull
(KVLCC2) is read and a patch extracted.
"""

from __future__ import annotations

import numpy as np
import pytest

from cad_helpers import (BOX_LENGTH_MM, KCS_IGES, KCS_SCALE, KVLCC2_IGES, KVLCC2_SCALE, box_hull_point, cad_model,
                         write_box_hull)
from mppf.core.errors import GeometryError, InputError
from mppf.core.polygon import closest_on_segments, contains, convex_outline, distance_to_outline
from mppf.geometry.cad import CadModel
from mppf.geometry.cad_query import closest_points
from mppf.geometry.extract import MAX_POINTS, GirthRegion, ProjectedRegion, extract_plate
from mppf.geometry.read import read_points
from mppf.geometry.stations import trace_stations
from mppf.geometry.surface import fit_plate


@pytest.fixture(scope="session")
def kcs():
    """The KCS hull model at model scale (mm), read once per test process (shared with test_cad)."""
    return cad_model(KCS_IGES, 1.0)


@pytest.fixture(scope="module")
def box(tmp_path_factory):
    with CadModel(write_box_hull(tmp_path_factory.mktemp("box") / "box.step")) as model:
        yield model


def _off_surface_mm(patch: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Height of points above a patch's bicubic spline fit (within 0.25 mm of the patch), in its frame.

    NaN outside the patch's outline inset by 100 mm (the fit is not asked to extrapolate).
    """
    fit = fit_plate(patch, kind="spline")
    local, probe = fit.frame.to_local(patch), fit.frame.to_local(points)
    height = fit.surface.evaluate(probe[:, 0], probe[:, 1])
    outline = convex_outline(local[:, :2])
    inner = contains(outline, probe[:, :2]) & (distance_to_outline(outline, probe[:, :2]) > 100.0)
    return np.where(inner, np.abs(probe[:, 2] - height), np.nan)


def _at_full_scale(plate):
    return plate.points * KCS_SCALE, plate.size_mm * KCS_SCALE, plate.area_mm2 * KCS_SCALE**2


def test_k1_cut_again_by_its_butts_and_seams(kcs, hull_dir):
    k1 = read_points(hull_dir / "K1_midbody_bilge.csv").points / KCS_SCALE
    x0, x1 = k1[:, 0].min(), k1[:, 0].max()
    # the seams: the girth of K1's points projected onto the traced middle station
    points, girth, _ = trace_stations(kcs, [0.5 * (x0 + x1)], 20000.0 / KCS_SCALE)
    ok = np.r_[True, np.diff(girth[0]) > 0]
    station, along = points[0][ok][:, 1:], girth[0][ok]
    foot, segment = closest_on_segments(k1[:, 1:], station[:-1], station[1:])
    g = along[segment] + np.linalg.norm(foot - station[segment], axis=1)
    plate = extract_plate(kcs, GirthRegion((x0, x1), (g.min(), g.max())), 50.0 / KCS_SCALE)
    full, size, area = _at_full_scale(plate)
    # the same plate: K1's lengths along x and round the bilge, on K1's surface, of K1's area
    grid = read_points(hull_dir / "K1_midbody_bilge.csv").points.reshape(61, 41, 3)
    k1_size = [np.median(np.linalg.norm(np.diff(grid, axis=a), axis=2).sum(axis=a)) for a in (0, 1)]
    assert plate.grid_shape == (62, 42) and full.shape == (62 * 42, 3)
    np.testing.assert_allclose(size, k1_size, rtol=0.01)  # K1: 3000 x 2031 mm on the surface
    off = _off_surface_mm(k1 * KCS_SCALE, full)
    assert np.isfinite(off).mean() > 0.75 and np.nanmax(off) < 1.0
    cells = [grid[:-1, :-1], grid[1:, :-1], grid[1:, 1:], grid[:-1, 1:]]
    k1_area = sum(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=2).sum()
                  for a, b, c in ((cells[0], cells[1], cells[2]), (cells[0], cells[2], cells[3])))
    assert area == pytest.approx(k1_area, rel=0.02)
    assert plate.chord_mm * KCS_SCALE < 0.2  # 50 mm cells on a 3.3 m bilge


def test_k3_cut_again_by_its_outline_seen_from_the_side(kcs, hull_dir):
    k3 = read_points(hull_dir / "K3_stern_saddle.csv").points
    outline = convex_outline(k3[:, [0, 2]]) / KCS_SCALE
    plate = extract_plate(kcs, ProjectedRegion(outline, "+y"), 50.0 / KCS_SCALE)
    full, size, area = _at_full_scale(plate)
    off = _off_surface_mm(k3, full)
    assert np.isfinite(off).mean() > 0.75 and np.nanmax(off) < 1.0
    assert plate.points.shape[0] < plate.grid_shape[0] * plate.grid_shape[1] or plate.points.shape[0] > 1000
    hits = closest_points(kcs, plate.points)
    assert hits.found.all() and hits.distance_mm.max() * KCS_SCALE < 1e-3  # every point on the exact surface


def test_a_girth_plate_across_the_bilge_has_its_size(box):
    plate = extract_plate(box, GirthRegion((1000.0, 4000.0), (6000.0, 8500.0)), 100.0)
    assert plate.grid_shape == (31, 26)
    np.testing.assert_allclose(plate.size_mm, [3000.0, 2500.0], atol=0.2)  # chords of 100 mm round a 3 m bilge
    assert plate.area_mm2 == pytest.approx(3000.0 * 2500.0, rel=1e-4)
    assert plate.faces.shape == (2 * 30 * 25, 3)
    # the seams: the first column at girth 6000 (flat bottom, y = 6000), the last at 8500 (on the bilge)
    grid = plate.points.reshape(31, 26, 3)
    np.testing.assert_allclose(grid[:, 0, 1:], np.broadcast_to(box_hull_point([6000.0])[0], (31, 2)), atol=0.05)
    np.testing.assert_allclose(grid[:, -1, 1:], np.broadcast_to(box_hull_point([8500.0])[0], (31, 2)), atol=0.05)


def test_kvlcc2_is_read_and_a_bilge_patch_extracted(tmp_path):
    with CadModel(KVLCC2_IGES, scale=KVLCC2_SCALE) as kvlcc2:
        length = np.ptp(kvlcc2.bounds_mm[:, 0])
        middle = kvlcc2.bounds_mm[:, 0].mean()
        plate = extract_plate(kvlcc2, GirthRegion((middle - 750.0, middle + 750.0), (27000.0, 29000.0)), 100.0)
        hits = closest_points(kvlcc2, plate.points)
    assert len(kvlcc2.faces) == 14 and 320_000 < length < 345_000  # KVLCC2: Lpp 320 m
    assert plate.grid_shape == (16, 21)
    np.testing.assert_allclose(plate.size_mm, [1500.0, 2000.0], atol=0.5)
    assert hits.found.all() and hits.distance_mm.max() < 1e-3
    assert plate.chord_mm < 1.0


def test_region_errors(box):
    with pytest.raises(GeometryError, match="do not meet the hull seen from \\+y"):
        extract_plate(box, ProjectedRegion([[30000, 100], [31000, 100], [31000, 900]], "+y"), 100.0)
    with pytest.raises(InputError, match="signed hull axis"):
        extract_plate(box, ProjectedRegion([[0, 0], [1, 0], [1, 1]], "y"), 100.0)
    with pytest.raises(InputError, match="more than"):
        extract_plate(box, GirthRegion((0.0, BOX_LENGTH_MM), (0.0, 20000.0)), 5.0)
    assert MAX_POINTS >= 1_000_000
    with pytest.raises(InputError, match="cannot be negative"):
        extract_plate(box, GirthRegion((0.0, 100.0), (-10.0, 100.0)), 50.0)
    with pytest.raises(InputError, match="must span a length"):
        extract_plate(box, GirthRegion((100.0, 100.0), (0.0, 100.0)), 50.0)


def test_the_bottom_seen_from_below(box):
    square = [[1000.0, 1000.0], [3000.0, 1000.0], [3000.0, 5000.0], [1000.0, 5000.0]]
    plate = extract_plate(box, ProjectedRegion(square, "-z"), 100.0)
    assert plate.grid_shape == (21, 41)
    np.testing.assert_allclose(plate.points[:, 2], 0.0, atol=1e-9)  # the bottom, not the deck edge above
