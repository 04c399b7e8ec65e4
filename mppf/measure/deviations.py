"""The design skin a scan measures, and the signed normal deviation of every scanned point.

A :class:`DesignSkin` is the fitted design surface moved to the skin the scanner saw
(``offset_mm`` along the normal: the design file is the mid-surface), its normal oriented
(``sign``), and the design's convex outline in its frame, plain and grown by the trim
margin. It gives the dense skin the scan is registered onto (:meth:`DesignSkin.dense_points`)
and, for a transform of the scan, the foot points, deviations and the outside and
trim-margin masks (:meth:`DesignSkin.deviate`). Lengths in mm.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace

import numpy as np
from scipy.spatial import cKDTree

from mppf.core.polygon import contains, convex_outline, distance_to_outline, offset_convex
from mppf.core.threads import worker_threads
from mppf.core.transform import apply_rotation, apply_tf
from mppf.geometry.frame import LocalFrame
from mppf.geometry.localize import FootPoints, foot_points
from mppf.geometry.surface import FittedPlate
from mppf.measure.localfit import spatial_query

DENSE_POINTS = 25000
"""Points of the dense design skin the scan is registered onto."""

ON_OUTLINE_MM = 1e-9
"""Points this close to an outline count as inside it (grid points on a straight edge)."""

PARALLEL_POINTS = 50000
"""From this many points the foot points are found on every core."""

OUTSIDE_SPACINGS = 1.5
"""A foot point beyond the outline is outside the design when farther than this many design
point spacings (plus the trim margin) from the design's points."""


def normal_sign(frame: LocalFrame, tf_press_design) -> float:
    """+1 or -1: the sign that makes the frame's normal point up in press coordinates (when known)."""
    if tf_press_design is None:
        return 1.0
    up = apply_rotation(np.asarray(tf_press_design, dtype=float), frame.axes[2:3])[0, 2]
    return 1.0 if up >= 0 else -1.0


@dataclass(frozen=True, eq=False)
class Deviation:
    """The deviations of a scan at one transform (measured -> design).

    Attributes
    ----------
    moved : (n, 3) float, mm
        The measured points in design coordinates.
    feet : FootPoints
        Their foot points on the design surface (design frame).
    deviation_mm : (n,) float
        Signed normal deviation from the skin (NaN where the foot point search failed).
    outside : (n,) bool
        The foot point failed or lies outside the design (beyond the outline grown by
        the margin, and away from the design's points).
    in_margin : (n,) bool
        Not outside, but beyond the design's (net) convex outline; all False without a margin.
    """

    moved: np.ndarray
    feet: FootPoints
    deviation_mm: np.ndarray
    outside: np.ndarray
    in_margin: np.ndarray

    @property
    def uv(self) -> np.ndarray:
        """(n, 2) foot points' (u, v) in the design frame, mm."""
        return np.asarray(self.feet.uv, dtype=float)


class DesignSkin:
    """The measured skin of a design (see the module docstring).

    Parameters
    ----------
    fitted : FittedPlate
        The design surface.
    design_points : (m, 3) float, mm
        The design points (the outline is theirs).
    sign : float
        +1 when positive deviations lie on the frame's +n side, -1 on its -n side.
    offset_mm : float
        The measured skin as a normal offset of the design (``+t/2``: the top skin).
    margin_mm : float
        Width of the trim margin the scan may still carry (>= 0).
    """

    def __init__(self, fitted: FittedPlate, design_points, sign: float, offset_mm: float, margin_mm: float):
        self.fitted, self.sign, self.offset_mm, self.margin_mm = fitted, float(sign), float(offset_mm), margin_mm
        self.frame = fitted.frame
        self.design_local = fitted.frame.to_local(design_points)
        self.uv = self.design_local[:, :2]
        self.outline = convex_outline(self.uv, "the design")
        self.grown = offset_convex(self.outline, margin_mm)
        self._tree = cKDTree(self.uv)
        self.spacing_mm = float(np.median(self._tree.query(self.uv, k=2)[0][:, 1]))

    @property
    def length_mm(self) -> float:
        """The design's largest in-plane extent."""
        return float(np.ptp(self.uv, axis=0).max())

    def at(self, uv) -> np.ndarray:
        """Skin points (k, 3) over the design-plane points ``uv`` (k, 2), design (world) coordinates."""
        surface = self.fitted.surface
        local = np.column_stack([uv, surface.evaluate(uv[:, 0], uv[:, 1])])
        return self.frame.to_world(local + (self.sign * self.offset_mm) * surface.normals(uv[:, 0], uv[:, 1]))

    def dense_points(self, n_points: int = DENSE_POINTS) -> np.ndarray:
        """The skin sampled densely: about ``n_points`` on a square grid over the grown outline (world).

        Beyond the design's edge the spline surface continues as its tangent plane (see
        :class:`mppf.geometry.spline.SplineSurface`): a dense target makes point-to-point
        ICP nearly a point-to-surface distance, without the bias of a coarse design grid.
        """
        lo, hi = self.grown.min(axis=0), self.grown.max(axis=0)
        step = max(float(np.sqrt(np.prod(hi - lo) / n_points)), 1e-6)
        uu, vv = np.meshgrid(np.arange(lo[0], hi[0] + 1e-9, step), np.arange(lo[1], hi[1] + 1e-9, step))
        uv = np.column_stack([uu.ravel(), vv.ravel()])
        return self.at(uv[_within(self.grown, uv, ON_OUTLINE_MM)])

    def deviate(self, measured, tf) -> Deviation:
        """Moved points, foot points, signed deviations, outside and trim-margin masks at ``tf``."""
        moved = apply_tf(tf, measured)
        feet = _foot_points(self.fitted.surface, self.frame.to_local(moved))
        distance = np.asarray(feet.distance_mm, dtype=float)
        deviation = np.where(np.isfinite(distance), self.sign * distance - self.offset_mm, np.nan)
        uv = np.asarray(feet.uv, dtype=float)
        outside = ~np.asarray(feet.converged, dtype=bool) | ~np.isfinite(deviation) | self.outside(uv)
        in_margin = np.zeros(len(outside), dtype=bool)
        if self.margin_mm > 0:
            in_margin = ~outside & ~_within(self.outline, uv, ON_OUTLINE_MM)
        return Deviation(moved, feet, deviation, outside, in_margin)

    def outside(self, uv) -> np.ndarray:
        """Foot points (n, 2) outside the design: beyond its grown outline and away from its points."""
        beyond = ~contains(self.grown, uv)
        rows = np.flatnonzero(beyond)  # only the points beyond the outline need the distance to the design's points
        reach = OUTSIDE_SPACINGS * max(self.spacing_mm, 1e-9) + self.margin_mm
        beyond[rows] = spatial_query(self._tree, uv[rows], 1)[0][:, 0] > reach
        return beyond

    def up_normals(self, uv) -> np.ndarray:
        """Unit design normals (k, 3) at design-plane points ``uv``, world, on the side of positive deviations."""
        return self.sign * apply_rotation(self.frame.tf_world_local, self.fitted.surface.normals(uv[:, 0], uv[:, 1]))

    def heights(self, measured):
        """``heights(tf)`` of the outline fit (:data:`mppf.registration.outline_fit.Heights`): the net
        plate's moved points, their up normals and deviations."""

        def net_plate_at(tf):
            dev = self.deviate(measured, tf)
            use = ~dev.outside & ~dev.in_margin
            return dev.moved[use], self.up_normals(dev.uv[use]), dev.deviation_mm[use]

        return net_plate_at


def _foot_points(surface, local: np.ndarray) -> FootPoints:
    """:func:`mppf.geometry.localize.foot_points` of many points in parts, one per thread (:func:`worker_threads`;
    each point's Newton iteration is its own: the same foot points; ``iterations`` is the slowest part's and
    ``mean_sq_change_mm2`` its last iteration's)."""
    n = local.shape[0]
    threads = worker_threads()
    if n < PARALLEL_POINTS or threads < 2:
        return foot_points(surface, local)
    parts = np.array_split(np.arange(n), threads)
    with ThreadPoolExecutor(threads) as pool:
        found = list(pool.map(lambda rows: foot_points(surface, local[rows]), parts))
    slowest = max(found, key=lambda f: f.iterations)
    joined = {name: np.concatenate([getattr(f, name) for f in found])
              for name in ("uv", "xyz", "distance_mm", "converged", "residual_mm")}
    return replace(slowest, **joined)


def _within(polygon, points_xy, tolerance_mm: float) -> np.ndarray:
    """:func:`mppf.core.polygon.contains` with a tolerance, the distances computed only for the points
    not inside (the costly part: (points x corners) work)."""
    inside = contains(polygon, points_xy)
    rest = np.flatnonzero(~inside)
    inside[rest] = distance_to_outline(polygon, points_xy[rest]) <= tolerance_mm
    return inside
