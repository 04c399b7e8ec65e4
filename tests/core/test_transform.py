"""4x4 transforms and rotations (mppf.core.transform), checked against scipy's rotations and by round trips."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mppf.core.errors import InputError
from mppf.core.transform import (
    apply_rotation,
    apply_tf,
    as_points,
    invert_tf,
    make_tf,
    matrix_to_quaternion,
    matrix_to_rotvec,
    quaternion_to_matrix,
    rotation_angle_deg,
    rotvec_to_matrix,
    tf_from_list,
    tf_to_list,
)

ROTVECS = [[0.0, 0.0, 0.0], [1e-7, -2e-7, 3e-8], [0.3, -0.2, 0.9], [np.pi, 0.0, 0.0], [0.0, -np.pi, 0.0],
           [1.0, 1.0, 1.0] / np.sqrt(3.0) * (np.pi - 1e-9), [2.0, 0.5, -1.0]]


@pytest.mark.parametrize("rotvec", ROTVECS)
def test_rotations_agree_with_scipy_and_round_trip(rotvec):
    expected = Rotation.from_rotvec(rotvec).as_matrix()
    matrix = rotvec_to_matrix(rotvec)
    np.testing.assert_allclose(matrix, expected, atol=1e-12)
    q = matrix_to_quaternion(matrix)
    assert q[0] >= 0.0 and np.linalg.norm(q) == pytest.approx(1.0)
    np.testing.assert_allclose(quaternion_to_matrix(q), expected, atol=1e-12)
    np.testing.assert_allclose(rotvec_to_matrix(matrix_to_rotvec(matrix)), expected, atol=1e-9)  # half turns too
    assert rotation_angle_deg(matrix) == pytest.approx(np.degrees(np.linalg.norm(rotvec)), abs=1e-5)


def test_quaternion_is_scalar_first_and_rotates_p_to_r_p():
    """A quarter turn about z, (cos 45, 0, 0, sin 45), takes x to y (the standard matrix, not its transpose)."""
    quarter = quaternion_to_matrix([np.cos(np.pi / 4), 0.0, 0.0, np.sin(np.pi / 4)])
    np.testing.assert_allclose(quarter @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(quaternion_to_matrix([2.0, 0.0, 0.0, 0.0]), np.eye(3))  # normalised first


def test_a_transform_maps_points_its_inverse_maps_them_back_and_vectors_only_turn():
    rng = np.random.default_rng(7)
    points = rng.uniform(-5000.0, 5000.0, (20, 3))
    tf_press_design = make_tf(rotvec_to_matrix([0.1, -0.4, 1.2]), [1500.0, -200.0, 30.0])
    moved = apply_tf(tf_press_design, points)
    np.testing.assert_allclose(apply_tf(invert_tf(tf_press_design), moved), points, atol=1e-9)
    np.testing.assert_allclose(invert_tf(tf_press_design) @ tf_press_design, np.eye(4), atol=1e-12)
    np.testing.assert_allclose(apply_rotation(tf_press_design, points) + tf_press_design[:3, 3], moved, atol=1e-9)
    assert rotation_angle_deg(tf_press_design) == pytest.approx(np.degrees(np.linalg.norm([0.1, -0.4, 1.2])))
    np.testing.assert_array_equal(make_tf(), np.eye(4))


def test_a_transform_goes_through_json_and_bad_ones_are_refused_naming_them():
    tf = make_tf(rotvec_to_matrix([0.0, 0.0, 0.5]), [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(tf_from_list(json.loads(json.dumps(tf_to_list(tf)))), tf)
    with pytest.raises(InputError, match="tf_design must be a finite 4x4 matrix, got shape \\(3, 3\\)"):
        tf_from_list(np.eye(3).tolist(), name="tf_design")
    with pytest.raises(InputError, match="finite"):
        tf_from_list([[float("nan")] * 4] * 4)
    with pytest.raises(InputError, match="is not a 4x4 list of numbers"):
        tf_from_list([["a", "b"]])


def test_points_must_be_n_by_3():
    assert as_points([[1, 2, 3]]).dtype == float
    with pytest.raises(InputError, match="scan must have shape \\(n, 3\\), got \\(4,\\)"):
        as_points([1, 2, 3, 4], name="scan")
