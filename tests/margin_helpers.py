"""Helpers of the trim-margin tests: a scan of the gross plate (net design + excess band), compared once a session."""

from __future__ import annotations

from functools import cache

import numpy as np
from scipy.spatial.transform import Rotation

from mppf.core.transform import apply_tf, make_tf
from mppf.measure.compare import compare
from mppf.measure.options import CompareOptions

MARGIN_MM = 100.0
HALF_U, HALF_V = 1500.0, 1000.0  # the net plate: 3000 x 2000 mm
BUMP_UV = (0.0, HALF_V + 60.0)   # a bump in the band, 60 mm beyond the net edge
BUMP_SIGMA_MM = 12.0


def height(u, v):
    """A saddle (radii 10 m and 12 m) with a small cubic and twist, so that its pose is unique (mm)."""
    return u**2 / (2 * 10000.0) - v**2 / (2 * 12000.0) + u**3 / 6e7 + u * v / 40000.0


def normals(u, v):
    zu = u / 10000.0 + u**2 / 2e7 + v / 40000.0
    zv = -v / 12000.0 + u / 40000.0
    n = np.column_stack([-zu, -zv, np.ones_like(u)])
    return n / np.linalg.norm(n, axis=1, keepdims=True)


def design():
    """The net design on a 40 mm grid."""
    uu, vv = np.meshgrid(np.arange(-HALF_U, HALF_U + 1, 40.0), np.arange(-HALF_V, HALF_V + 1, 40.0))
    return np.column_stack([uu.ravel(), vv.ravel(), height(uu, vv).ravel()])


def pose():
    return make_tf(Rotation.from_euler("xyz", [15, -30, 60], degrees=True).as_matrix(), [400.0, -1500.0, 250.0])


def bump(u, v):
    return 6.0 * np.exp(-((u - BUMP_UV[0]) ** 2 + (v - BUMP_UV[1]) ** 2) / (2 * BUMP_SIGMA_MM**2))


def scan(n=12000, with_bump=False, seed=5):
    """(u, v, scan): the surface sampled over the grown rectangle, 0.2 mm noise, moved by ``pose``.

    A few points sit on the bump's centre, so that it is seen whether or not it is there.
    """
    rng = np.random.default_rng(seed)
    extra = np.array([[0, 0], [4, 0], [-4, 0], [0, 4], [0, -4]], dtype=float) + BUMP_UV
    u = np.concatenate([rng.uniform(-HALF_U - MARGIN_MM, HALF_U + MARGIN_MM, n), extra[:, 0]])
    v = np.concatenate([rng.uniform(-HALF_V - MARGIN_MM, HALF_V + MARGIN_MM, n), extra[:, 1]])
    rise = bump(u, v) if with_bump else np.zeros(u.size)
    pts = np.column_stack([u, v, height(u, v)]) + rise[:, None] * normals(u, v)
    pts += rng.normal(0.0, 0.2, pts.shape)
    return u, v, apply_tf(pose(), pts)


def band(u, v):
    return (np.abs(u) > HALF_U) | (np.abs(v) > HALF_V)


@cache
def runs():
    """The gross scan with margin 100, the same scan's net points alone with margin 0."""
    u, v, points = scan()
    net = ~band(u, v)
    return {
        "u": u, "v": v,
        "gross": compare(design(), points, CompareOptions(margin_mm=MARGIN_MM)),
        "net": compare(design(), points[net], CompareOptions(tolerance_mm=2.5)),
        "net_mask": net,
    }
