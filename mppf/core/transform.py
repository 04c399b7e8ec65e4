"""Rigid transforms as 4x4 homogeneous matrices.

Transforms are named by their frames: ``tf_press_design`` maps design coordinates
into press coordinates, and they compose right to left
(``tf_a_c = tf_a_b @ tf_b_c``). Lengths are millimetres, angles radians unless a
name says ``_deg``.
"""

from __future__ import annotations

import numpy as np

from mppf.core.errors import InputError


def as_points(points, name: str = "points") -> np.ndarray:
    """Return ``points`` as a float array of shape (n, 3), or raise InputError.

    Parameters
    ----------
    points : (n, 3) array_like
    name : str
        Used in the error message.
    """
    arr = np.asarray(points, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"{name} must have shape (n, 3), got {arr.shape}")
    return arr


def make_tf(rotation=None, translation=None) -> np.ndarray:
    """Build a 4x4 transform from a (3, 3) rotation and a (3,) translation in mm."""
    tf = np.eye(4)
    if rotation is not None:
        tf[:3, :3] = np.asarray(rotation, dtype=float)
    if translation is not None:
        tf[:3, 3] = np.asarray(translation, dtype=float)
    return tf


def apply_tf(tf, points) -> np.ndarray:
    """Apply a 4x4 transform to points.

    Parameters
    ----------
    tf : (4, 4) float
    points : (n, 3) float, mm

    Returns
    -------
    (n, 3) float, mm
    """
    tf = np.asarray(tf, dtype=float)
    pts = np.asarray(points, dtype=float)
    return pts @ tf[:3, :3].T + tf[:3, 3]


def apply_rotation(tf, vectors) -> np.ndarray:
    """Rotate direction vectors (n, 3) by the rotation part of a 4x4 transform."""
    tf = np.asarray(tf, dtype=float)
    return np.asarray(vectors, dtype=float) @ tf[:3, :3].T


def invert_tf(tf) -> np.ndarray:
    """Inverse of a rigid 4x4 transform (exact for rotations: R^T, -R^T t)."""
    tf = np.asarray(tf, dtype=float)
    rot = tf[:3, :3]
    out = np.eye(4)
    out[:3, :3] = rot.T
    out[:3, 3] = -rot.T @ tf[:3, 3]
    return out


def quaternion_to_matrix(q) -> np.ndarray:
    """Rotation matrix of a unit quaternion ``q = (q0, q1, q2, q3)``, scalar first.

    This is the standard matrix (Horn 1987) such that ``x = R p`` rotates ``p``; the
    paper's eq. (2.8) prints its transpose (see docs/math.md, errata).
    """
    q0, q1, q2, q3 = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array(
        [
            [q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3, 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2)],
            [2 * (q1 * q2 + q0 * q3), q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3, 2 * (q2 * q3 - q0 * q1)],
            [2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3],
        ]
    )


def matrix_to_quaternion(rotation) -> np.ndarray:
    """Unit quaternion ``(q0, q1, q2, q3)``, scalar first and ``q0 >= 0``, of a (3, 3) rotation matrix.

    The inverse of :func:`quaternion_to_matrix`, by Shepperd's method (the largest of the
    four squared components is taken from the diagonal, the others from the off-diagonal
    terms): accurate for every angle, including half turns.
    """
    r = np.asarray(rotation, dtype=float)[:3, :3]
    trace = r[0, 0] + r[1, 1] + r[2, 2]
    pick = int(np.argmax([trace, r[0, 0], r[1, 1], r[2, 2]]))
    if pick == 0:
        q = np.array([1.0 + trace, r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    else:
        i, j, k = pick - 1, pick % 3, (pick + 1) % 3
        q = np.empty(4)
        q[0] = r[k, j] - r[j, k]
        q[1 + i] = 1.0 - trace + 2.0 * r[i, i]
        q[1 + j] = r[j, i] + r[i, j]
        q[1 + k] = r[k, i] + r[i, k]
    q /= np.linalg.norm(q)
    return -q if q[0] < 0 else q


def _half_sinc(angle: float) -> float:
    """sin(angle / 2) / angle, by its series near 0 (rad)."""
    if angle < 1e-4:
        return 0.5 - angle * angle / 48.0
    return float(np.sin(0.5 * angle) / angle)


def rotvec_to_matrix(rotvec) -> np.ndarray:
    """Rotation matrix (3, 3) of a rotation vector (3,): axis times angle in rad (right hand)."""
    v = np.asarray(rotvec, dtype=float).reshape(3)
    angle = float(np.sqrt(v @ v))
    return quaternion_to_matrix(np.concatenate([[np.cos(0.5 * angle)], _half_sinc(angle) * v]))


def matrix_to_rotvec(rotation) -> np.ndarray:
    """Rotation vector (3,) of a (3, 3) rotation matrix: axis times angle in rad, angle in [0, pi]."""
    q = matrix_to_quaternion(rotation)
    angle = 2.0 * float(np.arctan2(np.sqrt(q[1:] @ q[1:]), q[0]))
    return q[1:] / _half_sinc(angle)


def rotation_angle_deg(rotation) -> float:
    """Angle in degrees of a (3, 3) rotation matrix (0 for identity)."""
    rot = np.asarray(rotation, dtype=float)
    if rot.shape == (4, 4):
        rot = rot[:3, :3]
    cos = (np.trace(rot) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))


def tf_to_list(tf) -> list[list[float]]:
    """A 4x4 transform as row-major nested lists (for JSON)."""
    return [[float(v) for v in row] for row in np.asarray(tf, dtype=float)]


def tf_from_list(rows, name: str = "transform") -> np.ndarray:
    """Read a 4x4 row-major nested list back into an array, checking its shape."""
    try:
        tf = np.asarray(rows, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"{name} is not a 4x4 list of numbers: {exc}") from None
    if tf.shape != (4, 4) or not np.all(np.isfinite(tf)):
        raise InputError(f"{name} must be a finite 4x4 matrix, got shape {tf.shape}")
    return tf
