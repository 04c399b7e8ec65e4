"""The one rigid fit (mppf.core.rigid): a motion recovered in 3-D and in the plane."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from mppf.core.rigid import fit_rigid


def test_fit_rigid_recovers_a_motion_in_3d_and_in_the_plane():
    rng = np.random.default_rng(4)
    p = rng.uniform(-1000.0, 1000.0, (50, 3))
    rot = Rotation.from_euler("zyx", [40.0, -10.0, 5.0], degrees=True).as_matrix()
    shift = np.array([1.0e5, -2.0e4, 300.0])
    tf = fit_rigid(p, p @ rot.T + shift)
    np.testing.assert_allclose(tf[:3, :3], rot, atol=1e-10)
    np.testing.assert_allclose(tf[:3, 3], shift, atol=1e-6)
    angle = np.radians(-25.0)
    r2 = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    q = p[:, :2]
    tf2 = fit_rigid(q, q @ r2.T + [5.0, -7.0], weights=np.linspace(1.0, 2.0, len(q)))
    assert tf2.shape == (3, 3)
    np.testing.assert_allclose(tf2[:2, :2], r2, atol=1e-10)
    np.testing.assert_allclose(tf2[:2, 2], [5.0, -7.0], atol=1e-8)
