"""The ICP loop: stop criteria, and the closest points re-queried only where they may change (mppf.registration.icp)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from mppf.core.transform import apply_tf, invert_tf, make_tf, rotation_angle_deg
from mppf.geometry.frame import fit_frame
from mppf.registration import icp
from mppf.registration.settings import Matching
from mppf.registration.starts import principal_candidates
from mppf.registration.target import build_target
from registration_helpers import PLATE_POSE, motion_error, sampled_scan


def test_icp_stage_stops_when_the_closest_points_cycle():
    # point-to-plane on 4,000 scan points swings between a few closest-point sets here and
    # ran to the iteration limit (150) before the stall test
    design, scan = sampled_scan(20_000, 4000, seed=0)
    target = build_target(design)
    plane = Matching("plane")
    start = min(principal_candidates(fit_frame(scan), fit_frame(design)),
                key=lambda tf: rotation_angle_deg(tf @ invert_tf(PLATE_POSE)))
    stage = icp.run(target, scan, start, plane, icp.Stop(150, 1e-2, 1e-4, 1e-8))
    assert stage.converged and stage.iterations <= 3 * icp.STALL_ITERATIONS
    assert "cycle" in stage.stop_reason
    # the lowest-MSE transform comes back; its tilt and turn are as good as after 150 iterations
    # (0.059 degree; the in-plane shift is loose without the outline pin)
    assert icp.match(target, scan, stage.tf, plane).rms_mm <= min(stage.rms_history) * (1 + 1e-6)
    assert motion_error(stage.tf, PLATE_POSE, scan.mean(axis=0))[0] < 0.08

def test_nearest_gives_the_pairs_of_a_full_query_while_querying_fewer_points():
    # a scan moving towards its design in ever smaller steps, as in the late ICP iterations
    design, scan = sampled_scan(20_000, 3000, seed=1)
    target = build_target(design)
    nearest = icp.Nearest(target)
    queried = []
    original = target.tree.query

    def counting(points, *args, **kwargs):
        queried.append(len(points))
        return original(points, *args, **kwargs)

    target.tree = type("Counting", (), {"query": staticmethod(counting)})()
    big = make_tf(Rotation.from_euler("xyz", [0.3, -0.2, 0.5], degrees=True).as_matrix(), [4.0, -3.0, 2.0])
    steps = [big] * 3 + [make_tf(np.eye(3), [0.05 / k, 0.0, 0.0]) for k in range(4, 13)]
    tf = PLATE_POSE
    for step in steps:
        tf = step @ tf
        moved = apply_tf(tf, scan)
        dist, idx = nearest(moved)
        full_dist, full_idx = original(moved)
        np.testing.assert_array_equal(idx, full_idx)
        np.testing.assert_array_equal(dist, full_dist)  # bit for bit
    # the first query takes every point (and its second nearest), the late small steps almost none
    assert queried[0] == len(scan) and sum(queried[1:]) < 0.5 * 11 * len(scan)
    assert min(queried[4:]) < 0.1 * len(scan)


def test_nearest_queries_exact_ties_as_a_plain_query():
    # points midway between two target points: the cache takes the one the k-d tree gives
    grid = np.array([[x, y, 0.0] for x in range(0, 100, 10) for y in range(0, 100, 10)], dtype=float)
    target = build_target(grid)
    points = grid[:20] + [5.0, 0.0, 0.0]  # exactly between two columns of the grid
    dist, idx = icp.Nearest(target)(points)
    plain_dist, plain_idx = target.tree.query(points)
    np.testing.assert_array_equal(idx, plain_idx)
    np.testing.assert_array_equal(dist, plain_dist)
