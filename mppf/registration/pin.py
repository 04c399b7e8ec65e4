"""Outline pinning: the in-plane position of a shallow plate fixed by its outline.

The surface of a shallow plate barely fixes its position in its own plane (the
information matrix is nearly singular there, ``docs/math-registration.md``). When both
clouds cover the same plate, the moved source's convex outline in the target's plate
plane is brought onto the target's after every ICP step: area centroid onto area
centroid and, for elongated plates, major axis onto major axis. Lengths in mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from mppf.core.errors import GeometryError
from mppf.core.polygon import area, convex_inset, convex_outline
from mppf.core.transform import apply_tf, make_tf
from mppf.registration.target import RegistrationTarget, polygon_moments, query

COVERAGE_TOL = 0.12
"""Outline areas and extents of source and target within this fraction: same plate."""

ELONGATED = 1.3
"""Outline second-moment ratio above which the outline also pins the turn about the normal."""

PIN_BAND_FRACTION = 0.02
"""Width of the band of outline candidates along the convex outline, in plate sizes (sqrt area)."""

OUTLINE_NEIGHBOURS = 8
"""Neighbour rank whose distance tells isolated points (outliers) from the plate."""

ISOLATED = 4.0
"""Points whose neighbour distance exceeds this many times the median are not outline."""

PIN_TURN_DEG = 0.05
"""Point-to-plane: the outline also pins the turn about the normal when the surface fixes it
worse than this (one sigma, in degrees, for 1 mm noise on the source points). Point-to-point
always has it pinned (it sees the turn only through in-plane closest-point offsets)."""


def _major_axis_angle(moments: np.ndarray) -> tuple[float, float]:
    """(angle of the major axis in rad, ratio of the second moments major/minor)."""
    eigval, eigvec = np.linalg.eigh(moments)
    major = eigvec[:, 1]
    return float(np.arctan2(major[1], major[0])), float(eigval[1] / max(eigval[0], 1e-300))


@dataclass(frozen=True, eq=False)
class OutlinePin:
    """Fixes the in-plane position of the source by the outline in the target's plane.

    After each ICP step the moved source's convex outline (in the target's plate
    plane) is brought onto the target's: area centroid onto area centroid, and for
    elongated plates the major axis onto the major axis (a turn about the normal).
    The normal offset and the tilts stay as the surface fit gives them.
    """

    frame: object
    points: np.ndarray
    centroid_t: np.ndarray
    angle_t: float
    pin_turn: bool

    @property
    def free(self) -> np.ndarray:
        """(6,) bool: degrees of freedom (turns about u, v, n; shifts along u, v, n) left to ICP."""
        return np.array([True, True, not self.pin_turn, False, False, True])

    def apply(self, tf: np.ndarray) -> np.ndarray:
        """``tf`` corrected in-plane, (4, 4)."""
        local = self.frame.to_local(apply_tf(tf, self.points))[:, :2]
        _, centroid_s, moments_s = polygon_moments(local)
        turn = 0.0
        if self.pin_turn:
            angle_s, _ = _major_axis_angle(moments_s)
            turn = (self.angle_t - angle_s + np.pi / 2) % np.pi - np.pi / 2
        rot = Rotation.from_rotvec([0.0, 0.0, turn]).as_matrix()
        c_s = np.array([centroid_s[0], centroid_s[1], 0.0])
        c_t = np.array([self.centroid_t[0], self.centroid_t[1], 0.0])
        correction = make_tf(rot, c_t - rot @ c_s)
        return self.frame.tf_world_local @ correction @ self.frame.tf_local_world @ tf


def outline_candidates(frame, points: np.ndarray, sample: np.ndarray) -> np.ndarray:
    """Points of a cloud that may form its outline: a band along its convex outline.

    The convex outline is first taken from ``sample`` (a subsample of ``points``)
    without its isolated points (stray returns, outliers: their
    ``OUTLINE_NEIGHBOURS``-th neighbour farther than ``ISOLATED`` times the median
    such distance). The points of the whole cloud within ``PIN_BAND_FRACTION`` of the
    plate size of that outline, and not isolated themselves, are returned; they lie in
    the cloud's own plate plane (``frame``), so the outline can be recomputed cheaply in
    any pose.
    """

    def not_isolated(tree, pts):
        spacing = query(tree, pts, k=min(OUTLINE_NEIGHBOURS + 1, tree.n))[0][:, -1]
        return spacing <= ISOLATED * np.median(spacing)

    sample = sample[not_isolated(cKDTree(sample), sample)]
    try:
        outline = convex_outline(frame.to_local(sample)[:, :2])
    except GeometryError:
        return sample
    depth = convex_inset(outline, frame.to_local(points)[:, :2])
    band = points[np.abs(depth) <= PIN_BAND_FRACTION * np.sqrt(area(outline))]
    if band.shape[0] < 3:
        return band
    tree = cKDTree(points) if points.shape[0] > sample.shape[0] else cKDTree(sample)
    return band[not_isolated(tree, band)]


def outline_pin(target: RegistrationTarget, candidates: np.ndarray, tf: np.ndarray, *,
                require_coverage: bool, pin_turn: bool) -> tuple[OutlinePin | None, str]:
    """Build the outline pin at ``tf``, or say why not.

    Parameters
    ----------
    candidates : (k, 3) float, mm
        Source points along its outline (:func:`outline_candidates`).
    require_coverage : bool
        Only pin when both outlines have areas and extents within ``COVERAGE_TOL``.
    pin_turn : bool
        Also pin the turn about the normal (for elongated outlines).

    Returns
    -------
    (OutlinePin or None, str)
        The pin, and a description of the coverage test.
    """
    area_t, centroid_t, moments_t = target.outline()
    near = candidates
    if near.shape[0] < 10:
        return None, "too few source points on the outline"
    local = target.frame.to_local(apply_tf(tf, near))[:, :2]
    try:
        area_s, _, moments_s = polygon_moments(local)
    except GeometryError:
        return None, "the source has no outline in the target's plane"
    ext_s, ext_t = np.sqrt(np.linalg.eigvalsh(moments_s)), np.sqrt(np.linalg.eigvalsh(moments_t))
    ratios = np.concatenate([[area_s / area_t], ext_s / ext_t])
    coverage = (f"outline area ratio {ratios[0]:.3f}, extent ratios {ratios[1]:.3f} / {ratios[2]:.3f} "
                f"(source / target)")
    if require_coverage and np.any(np.abs(np.log(ratios)) > np.log1p(COVERAGE_TOL)):
        return None, coverage + ": the clouds do not cover the same plate"
    angle_t, elongation = _major_axis_angle(moments_t)
    pin = OutlinePin(frame=target.frame, points=near, centroid_t=centroid_t, angle_t=angle_t,
                     pin_turn=pin_turn and elongation > ELONGATED)
    return pin, coverage
