"""The closed-form rigid fit of paired points (Horn's unit quaternion), in 3-D and in the plane.

This is the paper's eq. (2.3)-(2.10) with its errata fixed (the symmetric 4 x 4 matrix Q,
the standard quaternion rotation matrix; see ``docs/math-registration.md``). Every rigid
fit in mppf (paired registration, each ICP step, the unfolding's placement, the outline
fit in the plane) calls :func:`fit_rigid`.
"""

from __future__ import annotations

import numpy as np

from mppf.core.transform import make_tf, quaternion_to_matrix


def fit_rigid(source, target, weights=None) -> np.ndarray:
    """Rigid transform best mapping paired points onto each other (weighted least squares).

    Parameters
    ----------
    source, target : (n, 3) or (n, 2) float, mm
        Pairs ``source[i] <-> target[i]`` (no checks: callers validate).
    weights : (n,) float >= 0, optional
        Pair weights (not all zero); default equal.

    Returns
    -------
    (4, 4) or (3, 3) float
        Homogeneous ``tf`` minimising ``sum w_i |target_i - (R source_i + t)|^2``; (3, 3)
        for plane points (a turn about the normal and an in-plane shift).
    """
    source = np.asarray(source, dtype=float)
    target = np.asarray(target, dtype=float)
    planar = source.shape[1] == 2
    if planar:  # the same fit in the plane z = 0: the rotation is then about z
        source = np.column_stack([source, np.zeros(len(source))])
        target = np.column_stack([target, np.zeros(len(target))])
    w = np.full(source.shape[0], 1.0 / source.shape[0]) if weights is None else weights / np.sum(weights)
    mu_p = w @ source  # (2.3)
    mu_x = w @ target  # (2.4)
    sigma = ((source - mu_p) * w[:, None]).T @ (target - mu_x)  # (2.5) cross-covariance
    anti = sigma - sigma.T
    delta = np.array([anti[1, 2], anti[2, 0], anti[0, 1]])
    trace = np.trace(sigma)
    q_mat = np.empty((4, 4))  # (2.6), symmetric 4 x 4
    q_mat[0, 0] = trace
    q_mat[0, 1:] = delta
    q_mat[1:, 0] = delta
    q_mat[1:, 1:] = sigma + sigma.T - trace * np.eye(3)
    eigval, eigvec = np.linalg.eigh(q_mat)
    rotation = quaternion_to_matrix(eigvec[:, np.argmax(eigval)])  # (2.7), (2.8) standard form
    translation = mu_x - rotation @ mu_p  # (2.9)
    tf = make_tf(rotation, translation)  # (2.10)
    if not planar:
        return tf
    out = np.eye(3)
    out[:2, :2] = tf[:2, :2]
    out[:2, 2] = tf[:2, 3]
    return out
