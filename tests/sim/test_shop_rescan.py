"""The dry-run shop's rescan: a new take of the same plate, in the pose of the cycle's first take, with its own
occlusion blobs, repeatable from the plate seed, the cycle and the rescan number."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from mppf.core.progress import NULL_REPORTER
from mppf.core.scanner import PressedStep, ScanContext
from mppf.geometry.read import read_points
from mppf.model.press import example_press_path, load_press
from mppf.sim.scanner import SimulatedScanner
from mppf.sim.shop import SimulatedPlateScanner

T = 20.0
OUTLINE = [[-1000.0, -600.0], [1000.0, -600.0], [1000.0, 600.0], [-1000.0, 600.0]]


def _context(press, work_dir):
    x, y = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    active = (np.abs(x) <= 1100) & (np.abs(y) <= 700)
    mid = 40.0 * (x / 1000.0) ** 2
    step = PressedStep(1, 1, np.where(active, mid + T / 2, press.upper.park_mm),
                       np.where(active, mid - T / 2, press.lower.park_mm), active)
    return ScanContext(plate_id="S", work_dir=work_dir, since_s=0.0, upper_mm=step.upper_mm, lower_mm=step.lower_mm,
                       active=active, steps=(step,), reporter=NULL_REPORTER)


def test_a_rescan_is_a_new_take_in_the_first_takes_pose(tmp_path):
    press = load_press(example_press_path())
    scanner = SimulatedPlateScanner(press, T, OUTLINE, seed=5, outlier_fraction=0.0)
    context = _context(press, tmp_path)
    first = read_points(scanner.acquire(1, context)).points
    rescan_path = scanner.rescan(1, 1, context)
    again = SimulatedPlateScanner(press, T, OUTLINE, seed=5, outlier_fraction=0.0)
    assert scanner.pressed == [[1, 1]]  # the rescan pressed nothing
    rescan = read_points(rescan_path).points
    assert rescan_path.name == "scan-cycle-01-rescan-1.ply" and not (tmp_path / (rescan_path.name + ".mark.json")).exists()
    # repeatable: the same seed, cycle and number give the same rescan (another process, after a resume)
    np.testing.assert_array_equal(read_points(again.rescan(1, 1, context)).points, rescan)
    # another take: other points, other blobs; the same frame: every rescan point lies on the first take's surface
    assert not np.array_equal(np.sort(rescan[:, 0]), np.sort(first[:, 0]))
    distance, _ = cKDTree(first).query(rescan)
    assert np.median(distance) < 15.0  # beside a first-take point (20 mm grid, 0.3 mm noise)
    # its blobs hide other parts of the plate: the union leaves less uncovered than the first take
    tf = SimulatedScanner(outlier_fraction=0.0, seed=5 * 1000 + 1).sample(scanner.last_formed).tf_scan_press  # the first take's
    plate_xy = np.linalg.solve(tf, np.c_[rescan, np.ones(len(rescan))].T).T[:, :2]
    first_xy = np.linalg.solve(tf, np.c_[first, np.ones(len(first))].T).T[:, :2]
    grid = np.stack(np.meshgrid(np.arange(-950, 951, 50.0), np.arange(-550, 551, 50.0)), axis=-1).reshape(-1, 2)
    missing_first = cKDTree(first_xy).query(grid)[0] > 60.0
    missing_union = missing_first & (cKDTree(plate_xy).query(grid)[0] > 60.0)
    assert missing_first.sum() > 20 and missing_union.sum() < 0.5 * missing_first.sum()


def test_a_given_pose_changes_nothing_else(tmp_path):
    """The pose may be given (a fixed station); the take's points relative to the plate are those of the random pose."""
    press = load_press(example_press_path())
    scanner = SimulatedPlateScanner(press, T, OUTLINE, seed=2)
    scanner.acquire(1, _context(press, tmp_path))
    formed = scanner.last_formed
    free = SimulatedScanner(seed=9).sample(formed)
    posed = SimulatedScanner(seed=9).sample(formed, tf_scan_press=np.eye(4))
    in_press = np.linalg.solve(free.tf_scan_press, np.c_[free.points, np.ones(len(free.points))].T).T[:, :3]
    np.testing.assert_allclose(posed.points, in_press, atol=1e-6)
    np.testing.assert_array_equal(posed.is_outlier, free.is_outlier)


def test_a_rescan_aimed_at_listed_areas_sees_them_whole_and_little_else(tmp_path):
    import dataclasses

    press = load_press(example_press_path())
    scanner = SimulatedPlateScanner(press, T, OUTLINE, seed=5, outlier_fraction=0.0)
    context = _context(press, tmp_path)
    first = read_points(scanner.acquire(1, context)).points
    area = [[-300.0, -200.0], [100.0, -200.0], [100.0, 150.0], [-300.0, 150.0]]
    aimed = dataclasses.replace(context, regions=({"kind": "uncovered", "corners_press_mm": area},))
    rescan = read_points(scanner.rescan(1, 1, aimed)).points
    tf = SimulatedScanner(outlier_fraction=0.0, seed=5 * 1000 + 1).sample(scanner.last_formed).tf_scan_press
    xy = np.linalg.solve(tf, np.c_[rescan, np.ones(len(rescan))].T).T[:, :2]
    # every point lies in the area or the rim of 3 spacings (60 mm) around it ...
    assert xy[:, 0].min() > -300 - 61 and xy[:, 0].max() < 100 + 61 and xy[:, 1].min() > -200 - 61
    assert xy[:, 1].max() < 150 + 61
    # (taken back to the press by the first take's pose: the same frame) and the area is seen whole, with no
    # occlusion blob in an aimed take, wherever the first take's blobs were
    grid = np.stack(np.meshgrid(np.arange(-290, 91, 20.0), np.arange(-190, 141, 20.0)), axis=-1).reshape(-1, 2)
    assert cKDTree(xy).query(grid)[0].max() < 25.0
    assert len(rescan) < 0.2 * len(first)
