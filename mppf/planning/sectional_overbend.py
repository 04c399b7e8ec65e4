"""Springback of a plate planned in sections: one over-bent target for the whole plate.

The design's whole-plate surface is over-bent once, in the design's own frame: along each principal
direction at the plate's centre its arc of curvature ``k`` is swapped for the over-bent arc of
curvature ``k'`` (:func:`mppf.forming.springback.loaded_curvature`, as
:func:`mppf.planning.overbend.overbend` does for one piece), and the design's departure from its
arcs is kept, along the target's normal. Every section presses that one target in its own pose,
so where two sections meet they press the same over-bent shape, rigidly moved, and the plate keeps
no step there. (Before, each section was over-bent about its own centre and the corrections were
blended at the borders: on plates split in two directions they disagreed by up to hundreds of mm,
``docs/sections.md``.)

**Material points, not a height field.** The over-bent target of a long plate is no graph over one
plane (7.5 m bent to R 6 m is over-bent to R 2.95 m for 20 mm steel: its ends turn 73 deg), so it is
given by where each material point lies on it: the design point at distance ``a`` along a principal
direction from the centre (arc length ``s = asin(k a) / k``) lies on the target at the same arc length,
``(sin(k' s) / k', (1 - cos(k' s)) / k')``. Each section presses a height field fitted to the target's
points over the section, in its own frame (:meth:`WholeTarget.section_fit`), where the target is one.
Where the over-bent arcs also form a graph over the whole plate, the point-by-point over-bend of a
curvature that varies over the plate (the field of :func:`~mppf.planning.overbend.overbend`) is added
along the normal too; on plates over-bent beyond that the principal arcs alone are used.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from mppf.core.errors import GeometryError
from mppf.core.kdtree import KDTree
from mppf.forming.springback import loaded_curvature
from mppf.geometry.curvature import curvatures
from mppf.geometry.surface import fit_plate
from mppf.planning.overbend import FLAT_RADIUS_MM, overbend
from mppf.planning.plan import SURFACE_DEGREE, SURFACE_KIND
from mppf.planning.plan_steps import overbend_report

POLY_ENOUGH_MM = 0.1
"""Largest residual of a polynomial fit still used for a surface every section presses (above: the B-spline,
if closer)."""

SAMPLE_MM = 50.0
"""Least spacing of the points added beyond the plate to fit a section's part of the over-bent target."""
OUTSIDE_SPACINGS = 1.5
"""A point this many design-point spacings from the nearest design point lies beyond the plate."""
EXTEND_NEIGHBOURS = 16
"""Beyond the plate the departure is continued by the plane through this many nearest design points."""


def closer_fit(poly, spline_fit):
    """The polynomial fit when it is within ``POLY_ENOUGH_MM``, else the B-spline (``spline_fit()``) if closer."""
    if poly.max_abs_mm <= POLY_ENOUGH_MM:
        return poly
    spline = spline_fit()
    return spline if spline.max_abs_mm < poly.max_abs_mm else poly


@dataclass(frozen=True, eq=False)
class WholeTarget:
    """The whole plate's over-bent target: where each material point of the design lies on it.

    Attributes
    ----------
    fitted : FittedPlate
        The design's whole-plate fit (world = the design's coordinates).
    tf_world_centre : (4, 4) float
        The tangent frame at the plate's centre on the design (x, y in the tangent plane, z its normal).
    directions : (2, 2) float
        Rows: the principal directions at the centre, unit (x, y) of the tangent frame.
    target_k, loaded_k : (2,) float
        The design's principal curvatures there and the over-bent ones (1/mm).
    field : object or None
        The point-by-point over-bend (a spline over the whole fit's (u, v), mm along the normal), or None.
    report : dict
        The job's springback report.
    correction : PointField or None
        A correction of the whole plate, mm along the normal at any world point (:meth:`corrected`), or None.
    """

    fitted: object
    tf_world_centre: np.ndarray
    directions: np.ndarray
    target_k: np.ndarray
    loaded_k: np.ndarray
    field: object
    report: dict
    correction: object = None

    def corrected(self, design, offset_mm) -> WholeTarget:
        """The target moved along its normal by ``offset_mm`` (n,) at the design points ``design`` (n, 3, world mm).

        A correction of the whole plate (``plan_sectional``'s ``target_offset_mm``): every section presses the
        moved target, so where sections meet they press the same correction. Between the design points the
        offset is interpolated linearly over the fit's (u, v); beyond them the nearest point's is taken.
        """
        return dataclasses.replace(self, correction=PointField(self.fitted.frame, design, offset_mm))

    def material_points(self, points, departure_mm=None) -> np.ndarray:
        """(n, 3) world mm: where the material of the design points ``points`` (n, 3, world mm) lies on the target.

        ``departure_mm`` (n,), optional: the departure from the principal arcs to keep, along the normal
        (default the points' own, :meth:`departure`; beyond the plate, continued from the plate's).
        """
        pts = np.asarray(points, dtype=float)
        xy, z = np.zeros((len(pts), 2)), np.zeros(len(pts))
        tangents = []
        for d, k, kk, ai in zip(self.directions, self.target_k, self.loaded_k, self._along(pts)):
            s = ai if abs(k) < 1e-15 else np.arcsin(np.clip(k * ai, -1.0, 1.0)) / k
            theta = kk * s
            if abs(kk) < 1e-15:
                along, up = s, np.zeros_like(s)
            else:
                along, up = np.sin(theta) / kk, (1.0 - np.cos(theta)) / kk
            xy += along[:, None] * d
            z += up
            tangents.append(np.column_stack([np.cos(theta)[:, None] * d, np.sin(theta)]))
        normal = np.cross(tangents[0], tangents[1])  # +z at the centre (beyond a quarter turn it turns over)
        normal *= np.sign(np.linalg.det(self.directions)) / np.linalg.norm(normal, axis=1, keepdims=True)
        offset = self.departure(pts) if departure_mm is None else np.asarray(departure_mm, dtype=float)
        on_target = np.column_stack([xy, z]) + offset[:, None] * normal
        return on_target @ self.tf_world_centre[:3, :3].T + self.tf_world_centre[:3, 3]

    def _centre_local(self, pts) -> np.ndarray:
        inv = np.linalg.inv(self.tf_world_centre)
        return pts @ inv[:3, :3].T + inv[:3, 3]

    def _along(self, pts) -> np.ndarray:
        """(2, n): distance of each point from the centre along each principal direction (mm)."""
        return self.directions @ self._centre_local(pts)[:, :2].T

    def departure(self, pts) -> np.ndarray:
        """(n,): the design points' departure from the principal arcs, along the normal, and the field (mm)."""
        lift, lean = self._centre_local(pts)[:, 2], np.ones(len(pts))
        for k, ai in zip(self.target_k, self._along(pts)):
            ka = np.clip(k * ai, -1.0, 1.0)
            lift = lift - ai * ka / (1.0 + np.sqrt(1.0 - ka * ka))  # the arc's height k a^2 / (1 + sqrt(1 - k^2 a^2))
            lean = lean * np.sqrt(1.0 - ka * ka)
        offset = lift * lean
        if self.field is not None:
            uv = self.fitted.frame.to_local(pts)[:, :2]
            offset = offset + self.field.ev(uv[:, 0], uv[:, 1])
        if self.correction is not None:
            offset = offset + self.correction(pts)
        return offset

    def section_fit(self, design_on_bed, reach_mm: float):
        """The target over one section as a height field in its own frame (a :class:`FittedPlate`).

        Parameters
        ----------
        design_on_bed : (m, 3) float, world mm
            The design points over the section's bed.
        reach_mm : float
            How far past them the fit must hold (trim margin, trim allowance).

        Returns
        -------
        FittedPlate
            Fitted to the target's points of the design points over the section and, beyond the plate
            (out to ``reach_mm``), of points continuing the arcs: the degree-4 polynomial, or the B-spline
            when the polynomial misses by more than ``POLY_ENOUGH_MM`` and the spline is closer.
        """
        frame = self.fitted.frame
        local = frame.to_local(design_on_bed)
        tree = KDTree(local[:, :2])
        spacing = float(np.median(tree.query(local[:, :2], k=2)[0][:, 1]))
        lo, hi = local[:, :2].min(axis=0) - reach_mm, local[:, :2].max(axis=0) + reach_mm
        step = max(spacing, SAMPLE_MM)
        gu, gv = np.meshgrid(np.arange(lo[0], hi[0] + step, step), np.arange(lo[1], hi[1] + step, step))
        grid = np.column_stack([gu.ravel(), gv.ravel()])
        # beyond the plate the arcs carry on, with the departure of the plate's nearest point (a surface fit
        # beyond its data is no extension)
        beyond = tree.query(grid)[0] > OUTSIDE_SPACINGS * spacing
        departure = self.departure(design_on_bed)
        near = tree.query(grid[beyond], k=min(EXTEND_NEIGHBOURS, len(local)))[1]
        extension = frame.to_world(np.column_stack([grid[beyond], local[near[:, 0], 2]]))
        points = np.vstack([self.material_points(design_on_bed, departure),
                            self.material_points(extension, _linear_at(local[near, :2], departure[near],
                                                                       grid[beyond]))])
        poly = fit_plate(points, degree=SURFACE_DEGREE, kind=SURFACE_KIND)
        return closer_fit(poly, lambda: fit_plate(points, kind="spline"))


class PointField:
    """A value at each of n points, interpolated linearly over a frame's (u, v); the nearest point's beyond them.

    Parameters
    ----------
    frame : LocalFrame
        The frame whose (u, v) the values are interpolated over (the whole plate's fit).
    points : (n, 3) float, world mm
    values_mm : (n,) float, mm

    Calling it with ``pts`` (m, 3, world mm) gives the values (m,) mm there.
    """

    def __init__(self, frame, points, values_mm):
        from scipy.interpolate import LinearNDInterpolator

        self.frame = frame
        uv = frame.to_local(np.asarray(points, dtype=float))[:, :2]
        self.values = np.asarray(values_mm, dtype=float).reshape(len(uv))
        self.linear, self.tree = LinearNDInterpolator(uv, self.values), KDTree(uv)

    def __call__(self, pts) -> np.ndarray:
        uv = self.frame.to_local(np.asarray(pts, dtype=float))[:, :2]
        out = self.linear(uv)
        missing = ~np.isfinite(out)
        if missing.any():
            out[missing] = self.values[self.tree.query(uv[missing])[1]]
        return out


def _linear_at(xy, values, at) -> np.ndarray:
    """(m,): per row, the least-squares plane through ``values`` (m, k) at ``xy`` (m, k, 2), evaluated at ``at`` (m, 2)."""
    rel = xy - at[:, None, :]
    a = np.concatenate([np.ones(rel.shape[:2] + (1,)), rel], axis=2)  # the plane's value at ``at`` is its constant
    ata = np.einsum("mki,mkj->mij", a, a) + 1e-9 * np.eye(3)
    atb = np.einsum("mki,mk->mi", a, values)
    return np.linalg.solve(ata, atb[..., None])[:, 0, 0]


def whole_target(whole, design, press, thickness_mm: float, material, margin_mm: float) -> WholeTarget:
    """The over-bent target of the whole plate, for every section to press in its own pose.

    Parameters
    ----------
    whole : FittedPlate
        The design's whole-plate fit (the surface every section would press without springback).
    design : (n, 3) float, mm
        The design points (their reach from the centre decides whether the field can be used).
    press : PressConfig
    thickness_mm : float
    material : Material
    margin_mm : float
        Trim margin.
    """
    z, zu, zv = (float(np.ravel(x)[0]) for x in whole.surface.derivatives(np.zeros(1), np.zeros(1))[:3])
    normal = np.array([-zu, -zv, 1.0]) / np.sqrt(1.0 + zu * zu + zv * zv)
    x_axis = np.array([1.0, 0.0, zu]) / np.sqrt(1.0 + zu * zu)
    rot = np.column_stack([x_axis, np.cross(normal, x_axis), normal])  # centre tangent frame in the fit's frame
    tf_local_centre = np.eye(4)
    tf_local_centre[:3, :3], tf_local_centre[:3, 3] = rot, [0.0, 0.0, z]
    tf_world_centre = whole.frame.tf_world_local @ tf_local_centre
    curv = curvatures(whole.surface, np.zeros(1), np.zeros(1))
    dirs_uv = np.vstack([curv.dir1[0], curv.dir2[0]])
    local = whole.frame.to_local(design)
    target = np.array([_arc_curvature(whole.surface, d, local[:, :2] @ d, k)
                       for d, k in zip(dirs_uv, (curv.k1[0], curv.k2[0]))])
    dirs3 = np.column_stack([dirs_uv, dirs_uv @ [zu, zv]]) @ rot  # into the tangent frame
    directions = dirs3[:, :2] / np.linalg.norm(dirs3[:, :2], axis=1, keepdims=True)
    flat = np.abs(target) < 1.0 / FLAT_RADIUS_MM
    loaded = np.where(flat, target, loaded_curvature(np.where(flat, 0.0, target), thickness_mm, material))
    if BIAXIAL:
        loaded = biaxial_loaded(target, loaded, thickness_mm, material)
    reach = float(np.linalg.norm(local[:, :2], axis=1).max()) + margin_mm \
        + press.trim_allowance_mm
    try:  # where the over-bent arcs are a graph over the whole plate: the point-by-point field as well
        field, how = overbend(whole.surface, thickness_mm, material, reach).field, "principal arcs and field"
    except GeometryError:
        field, how = None, "principal arcs only: over-bent beyond a height field over the whole plate"
    report = {**overbend_report(_Radii(target, loaded, dirs_uv)),
              "method": f"one over-bent target for the whole plate ({how}), pressed by every section in its own "
                        "pose (docs/sections.md)"}
    return WholeTarget(fitted=whole, tf_world_centre=tf_world_centre, directions=directions, target_k=target,
                       loaded_k=loaded, field=field, report=report)


BIAXIAL = False
"""Over-bend the two principal directions together (:func:`biaxial_loaded`), not each on its own: a study switch
(``benchmarks/bench_loop_sectional.py --biaxial``), off: measured on the steel-plate simulator it brings the
first press of three of five long plates closer and two further (``benchmarks/results/2026-12-06-sectional-aim.md``)."""


def biaxial_loaded(target_k, uniaxial_k, thickness_mm: float, material) -> np.ndarray:
    """(2,) 1/mm: the loaded principal curvatures whose release leaves ``target_k`` (2,) in both directions.

    The plate's biaxial elastic-plastic bending law (:class:`mppf.correct.through_thickness.BendingLaw`, the
    nominal material, no hardening) inverted from a virgin, flat plate by the correction's own inversion
    (:func:`mppf.correct.invert.invert`): bent along one direction and held flat across, a plate springs back
    with an anticlastic curvature across (a cylinder of R 20 m in 20 mm steel bows by 6 mm over 2.4 m); the
    over-bend across cancels it. Where the inversion does not reach the target within four elastic-limit
    curvatures and four targets, the directions' own over-bends ``uniaxial_k``
    (:func:`mppf.forming.springback.loaded_curvature`).
    """
    from mppf.correct.invert import invert
    from mppf.correct.through_thickness import BendingLaw, BendingState

    law = BendingLaw(thickness_mm, material.youngs_modulus_mpa, material.poisson, material.yield_stress_mpa)
    target = np.asarray(target_k, dtype=float)
    if not np.any(target):
        return np.zeros(2)
    flat = np.zeros((1, 3))
    reach = 4.0 * law.elastic_limit_per_mm + 4.0 * float(np.max(np.abs(target)))
    loaded, reached = invert(law, BendingState.virgin(1), flat, flat, np.array([[target[0], target[1], 0.0]]), reach)
    return loaded[0, :2] if reached[0] else np.asarray(uniaxial_k, dtype=float)


def _arc_curvature(surface, direction_uv, along_mm, at_centre: float) -> float:
    """Curvature (1/mm) of the circle best fitting the surface along a principal line through the centre.

    The surface's heights along the line over the plate's extent there (``along_mm``: the design's
    distances along it), by the algebraic circle fit; a B-spline's curvature at one point is not
    the arc's (over a 7.5 m cylinder R 6 m, 6015 m). Directions flatter than ``FLAT_RADIUS_MM`` keep
    ``at_centre``.
    """
    if abs(at_centre) < 1.0 / FLAT_RADIUS_MM:
        return float(at_centre)
    t = np.linspace(float(np.min(along_mm)), float(np.max(along_mm)), 201)
    w = np.asarray(surface.evaluate(t * direction_uv[0], t * direction_uv[1]), dtype=float)
    coef = np.linalg.lstsq(np.column_stack([t, w, np.ones_like(t)]), -(t * t + w * w), rcond=None)[0]
    centre_w = -coef[1] / 2.0
    radius = float(np.sqrt(coef[0] ** 2 / 4.0 + centre_w ** 2 - coef[2]))
    w0 = float(surface.evaluate(np.zeros(1), np.zeros(1))[0])
    return float(np.sign(centre_w - w0)) / radius


@dataclass(frozen=True)
class _Radii:
    """What :func:`mppf.planning.plan_steps.overbend_report` reads of an over-bent surface."""

    target_k: np.ndarray
    loaded_k: np.ndarray
    directions: np.ndarray
