"""Outline pinning: the in-plane pose fixed by the outline only where the surface leaves it free.

The surface of a shallow plate barely fixes its position in its own plane (the information
matrix is nearly singular there, ``docs/math-registration.md``); a curved plate's surface
fixes it far better than any outline can. So the outline is weighed against the surface:

- the outline measures the in-plane pose: the moved source's convex outline, in the
  target's plate plane, against the target's (area centroid onto area centroid, and for
  elongated plates major axis onto major axis); its uncertainty follows from the two clouds'
  point spacings along their outlines (:func:`outline_sigma`);
- the surface's uncertainty of the same three degrees of freedom comes from the
  point-to-plane information matrix (6 x 6) and the residual (:func:`surface_covariance`);
- their Kalman gain ``S = P (P + R)^-1`` (3 x 3) says, per direction, how much the outline
  decides: about 1 where the surface leaves the pose free (a cylinder's slide, a shallow
  plate), about 0 where the surface fixes it. :class:`OutlinePin` mixes, in every ICP step,
  the in-plane move the surface wants with the one the outline wants by ``S``; the other
  degrees of freedom follow the metric.

Between a flat and a curved plate the surface says nothing true about the in-plane pose:
the outline decides alone (``S = I``, a hard pin). Lengths in mm, turns in rad.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.errors import GeometryError
from mppf.core.kdtree import KDTree
from mppf.core.polygon import area, convex_inset, convex_outline, perimeter
from mppf.core.transform import apply_tf, make_tf, rotvec_to_matrix
from mppf.registration.target import RegistrationTarget, polygon_moments

COVERAGE_TOL = 0.12
"""Outline areas and extents of source and target within this fraction: same plate."""

ELONGATED = 1.3
"""Outline second-moment ratio above which the outline also measures the turn about the normal."""

PIN_BAND_FRACTION = 0.02
"""Width of the band of outline candidates along the convex outline, in plate sizes (sqrt area)."""

OUTLINE_NEIGHBOURS = 8
"""Neighbour rank whose distance tells isolated points (outliers) from the plate."""

ISOLATED = 4.0
"""Points whose neighbour distance exceeds this many times the median are not outline."""

CENTROID_FACTOR = 1.0
"""One-sigma error of a sampled outline's area centroid, in ``spacing / sqrt(spacings along the outline)``
(measured on random and jittered samples of a 3 x 1.5 m plate: 0.4 - 0.75 of it per axis)."""

TURN_FACTOR = 0.6
"""One-sigma error of its major axis, in ``centroid sigma * sqrt(l1 + l2) / (l1 - l2)`` (the second
moments' eigenvalues; measured: 0.3 - 0.57)."""

FREE = 1e-12
"""Surface information below this fraction of the largest counts as none (the covariance is capped there)."""


def _major_axis_angle(moments: np.ndarray) -> tuple[float, float]:
    """(angle of the major axis in rad, ratio of the second moments major/minor)."""
    eigval, eigvec = np.linalg.eigh(moments)
    major = eigvec[:, 1]
    return float(np.arctan2(major[1], major[0])), float(eigval[1] / max(eigval[0], 1e-300))


def outline_sigma(n_points: int, outline: np.ndarray) -> float:
    """One-sigma error (mm) of the area centroid of the convex outline of ``n_points`` spread over ``outline``."""
    spacing = np.sqrt(abs(area(outline)) / max(n_points, 1))
    along = max(perimeter(outline) / max(spacing, 1e-12), 1.0)
    return float(CENTROID_FACTOR * spacing / np.sqrt(along))


@dataclass(frozen=True, eq=False)
class OutlinePin:
    """The outline's say in the in-plane pose (see the module docstring).

    Attributes
    ----------
    frame : LocalFrame
        The target's plate frame: in-plane axes u, v, normal n.
    points : (k, 3) float
        Source points along its outline (:func:`outline_candidates`), source coordinates.
    centroid_t : (2,) float
        The target outline's area centroid in its plate plane; the centre of the turns.
    angle_t : float
        Its major axis (rad).
    rows : tuple of int
        The degrees of freedom the outline measures, of (turn about u, v, n; shift along
        u, v, n): (3, 4) or, elongated, (2, 3, 4).
    share : (m, m) float
        The gain ``S``: how much of the outline's wish is taken, in those degrees of freedom.
    hard : bool
        The outline decides alone (flat against curved): ``share`` is the identity.
    tangential : bool
        With the point metric: its own in-plane pulls are information (clouds sampled
        alike), so the surface's wish is the metric's step; else the point-to-plane step's.
    """

    frame: object
    points: np.ndarray
    centroid_t: np.ndarray
    angle_t: float
    rows: tuple
    share: np.ndarray
    hard: bool = False
    tangential: bool = False

    @property
    def centre(self) -> np.ndarray:
        """(3,) the centre of the turns of an ICP step (the target outline's centroid), world mm."""
        return self.frame.to_world(np.array([[self.centroid_t[0], self.centroid_t[1], 0.0]]))[0]

    @property
    def weights(self) -> dict:
        """The outline's share per degree of freedom it measures (diagonal of ``share``), e.g. ``{"t_u": 0.98}``."""
        names = {2: "r_n", 3: "t_u", 4: "t_v"}
        return {names[r]: float(np.clip(self.share[i, i], 0.0, 1.0)) for i, r in enumerate(self.rows)}

    def wish(self, tf: np.ndarray) -> np.ndarray:
        """(m,) the move the outline wants at ``tf``: turn about n (rad) and shift of the centre (mm)."""
        local = self.frame.to_local(apply_tf(tf, self.points))[:, :2]
        _, centroid_s, moments_s = polygon_moments(local)
        turn = 0.0
        if 2 in self.rows:
            angle_s, _ = _major_axis_angle(moments_s)
            turn = (self.angle_t - angle_s + np.pi / 2) % np.pi - np.pi / 2
        c, s = np.cos(turn), np.sin(turn)
        shift = np.array([[c, -s], [s, c]]) @ (self.centroid_t - centroid_s)
        return np.array(([turn] if 2 in self.rows else []) + [shift[0], shift[1]])

    def apply(self, tf: np.ndarray) -> np.ndarray:
        """``tf`` moved in-plane by all of the outline's wish (the hard pin), (4, 4)."""
        wish = self.wish(tf)
        turn = wish[0] if 2 in self.rows else 0.0
        rot = rotvec_to_matrix([0.0, 0.0, turn])
        c = np.array([self.centroid_t[0], self.centroid_t[1], 0.0])
        correction = make_tf(rot, c + np.array([wish[-2], wish[-1], 0.0]) - rot @ c)
        return self.frame.tf_world_local @ correction @ self.frame.tf_local_world @ tf


def surface_covariance(hess: np.ndarray, sigma_mm: float) -> np.ndarray:
    """Covariance (6, 6) of the pose from the point-to-plane information ``hess`` and the residual scale.

    ``hess`` is in (turn rad about u, v, n; shift mm along u, v, n) about the pin's centre;
    information below :data:`FREE` of the largest (scaled) counts as none.
    """
    eigval, eigvec = np.linalg.eigh(hess)
    floor = FREE * max(float(eigval[-1]), 1e-300)
    return (eigvec / np.maximum(eigval, floor)) @ eigvec.T * sigma_mm**2


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
        spacing = tree.query(pts, k=min(OUTLINE_NEIGHBOURS + 1, tree.n))[0][:, -1]
        return spacing <= ISOLATED * np.median(spacing)

    sample = sample[not_isolated(KDTree(sample), sample)]
    try:
        outline = convex_outline(frame.to_local(sample)[:, :2])
    except GeometryError:
        return sample
    depth = convex_inset(outline, frame.to_local(points)[:, :2])
    band = points[np.abs(depth) <= PIN_BAND_FRACTION * np.sqrt(area(outline))]
    if band.shape[0] < 3:
        return band
    tree = KDTree(points) if points.shape[0] > sample.shape[0] else KDTree(sample)
    return band[not_isolated(tree, band)]


def outline_pin(target: RegistrationTarget, candidates: np.ndarray, n_source: int, tf: np.ndarray, *,
                require_coverage: bool, covariance, hard: bool, tangential: bool = False
                ) -> tuple[OutlinePin | None, str]:
    """Build the outline pin at ``tf``, or say why not.

    Parameters
    ----------
    candidates : (k, 3) float, mm
        Source points along its outline (:func:`outline_candidates`).
    n_source : int
        Points of the whole source (its spacing sets its outline's uncertainty).
    require_coverage : bool
        Only pin when both outlines have areas and extents within ``COVERAGE_TOL``.
    covariance : callable
        ``covariance(centre)``: the surface's pose covariance (6, 6) about the world point
        ``centre`` (:func:`surface_covariance`); not called for a hard pin.
    hard : bool
        The outline decides the in-plane pose alone.
    tangential : bool
        See :attr:`OutlinePin.tangential`.

    Returns
    -------
    (OutlinePin or None, str)
        The pin, and a description of the coverage test.
    """
    area_t, centroid_t, moments_t = target.outline()
    if candidates.shape[0] < 10:
        return None, "too few source points on the outline"
    local = target.frame.to_local(apply_tf(tf, candidates))[:, :2]
    try:
        area_s, _, moments_s = polygon_moments(local)
        outline_s = convex_outline(local)
    except GeometryError:
        return None, "the source has no outline in the target's plane"
    ext_s, ext_t = np.sqrt(np.linalg.eigvalsh(moments_s)), np.sqrt(np.linalg.eigvalsh(moments_t))
    ratios = np.concatenate([[area_s / area_t], ext_s / ext_t])
    coverage = (f"outline area ratio {ratios[0]:.3f}, extent ratios {ratios[1]:.3f} / {ratios[2]:.3f} "
                f"(source / target)")
    if require_coverage and np.any(np.abs(np.log(ratios)) > np.log1p(COVERAGE_TOL)):
        return None, coverage + ": the clouds do not cover the same plate"
    angle_t, elongation = _major_axis_angle(moments_t)
    rows = (2, 3, 4) if elongation > ELONGATED else (3, 4)
    pin = OutlinePin(frame=target.frame, points=candidates, centroid_t=centroid_t, angle_t=angle_t, rows=rows,
                     share=np.eye(len(rows)), hard=hard)
    if hard:
        return pin, coverage
    outline_t = convex_outline(target.frame.to_local(target.points)[:, :2])
    sigma_c = np.hypot(outline_sigma(n_source, outline_s), outline_sigma(target.n_points, outline_t))
    lam = np.linalg.eigvalsh(moments_t)
    sigma_turn = TURN_FACTOR * sigma_c * np.sqrt(lam.sum()) / max(lam[1] - lam[0], 1e-300)
    noise = np.array(([sigma_turn] if 2 in rows else []) + [sigma_c, sigma_c]) ** 2
    surface = covariance(pin.centre)[np.ix_(rows, rows)]
    share = surface @ np.linalg.inv(surface + np.diag(noise))
    return OutlinePin(frame=target.frame, points=candidates, centroid_t=centroid_t, angle_t=angle_t, rows=rows,
                      share=share, tangential=tangential), coverage
