"""Compare a measured (scanned) plate with its design: register, deviate, summarise.

The steps of :func:`compare` (the math is in ``docs/compare.md``):

1. Fit the design surface: the design's own frame (best-fit plane) and a bicubic
   B-spline height field ``w = D(u, v)`` (:func:`mppf.geometry.surface.fit_plate`).
2. Offset the design to the measured skin: the design file is the mid-surface, a scanner
   sees a skin; ``offset_mm`` moves the design along its normal (``+t/2`` for the top skin).
3. Register the scan onto the (offset) design skin sampled densely from the fitted
   surface (:func:`mppf.registration.register.register_icp`): point-to-point ICP from the principal
   axes (keeps the scan centred on the plate), then point-to-plane ICP with trimmed,
   Huber-weighted pairs (accurate along the normal, ignores outliers); the point result
   is kept if the plane stage slid part of the scan off the design's edge. With punch
   positions (the loop) the outline then fixes the in-plane pose and the deviations'
   best plane the out-of-plane pose (:func:`_outline_refit`).
4. Signed normal deviation of EVERY measured point: its foot point on the design surface
   (:func:`mppf.geometry.localize.foot_points`), distance along the design normal minus the offset.
   Positive = the measured plate lies on the +normal side of the design ("above").
5. Outliers: a point whose deviation differs from a robust local plane through its
   neighbours' deviations by more than a robust threshold (6 sigma of those differences,
   at least 0.5 mm) is flagged and left out of the statistics; so are points whose foot
   point falls outside the design.
   Smooth shape errors (a bump, springback) are NOT outliers: their neighbours agree.
6. Statistics of the inliers (RMS, largest absolute, mean, percent within tolerance,
   histogram) and, given the punch positions, the deviation at each punch.

A trim margin (``margin_mm``: the excess band the scanned plate still carries around the
net outline) grows the registration target, the size check and the outline fit by the
margin; points in the band are measured (against the design surface's extension past its
edge) and used for the punch deviations, but left out of the statistics.

Which way is "+normal": with ``tf_press_design`` the design normal pointing up in press
coordinates (+z); without it the normal of the design's frame (:mod:`mppf.geometry.frame`: the
side from which a curved plate looks concave, like a bowl on the press bed).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import RBFInterpolator
from matplotlib.path import Path as PolygonPath
from scipy.spatial import ConvexHull, cKDTree
from scipy.spatial.transform import Rotation

from mppf.core.errors import GeometryError, InputError
from mppf.geometry.frame import LocalFrame, fit_frame
from mppf.geometry.localize import foot_points
from mppf.core.polygon import offset_convex
from mppf.registration.register import Registration, principal_candidates, register_icp
from mppf.geometry.surface import fit_plate
from mppf.core.transform import apply_rotation, apply_tf, as_points, make_tf, rotation_angle_deg, tf_to_list

OUTLIER_NEIGHBOURS = 16
"""Neighbours (in the design plane) whose median deviation a point is compared with."""

OUTLIER_SIGMAS = 6.0
"""A point is an outlier when it differs from its neighbours by more than this many robust sigmas."""

OUTLIER_FLOOR_MM = 0.5
"""... and by more than this (so that a noise-free scan has no outliers)."""

MIN_POINTS = 30
#: neighbours (the point included) of the local plane that gives the form deviation: the
#: plate's own deviation with the scanner's point noise averaged out (see ``form_deviation_mm``)
FORM_NEIGHBOURS = 12
"""Fewest measured points a comparison accepts."""

SIZE_RATIO = (0.3, 1.3)
"""Accepted range of the scan's length (largest in-plane extent) over the design's."""

MATCH_FRACTION = 0.5
"""At least this fraction of the measured points must lie near the design (else: wrong plate)."""

OVERHANG_FRACTION = 0.02
"""Point-to-plane is rejected when it leaves this much more of the scan beyond the design's edge."""

DENSE_POINTS = 25000
"""Points of the dense design skin the scan is registered onto."""

OUTLINE_ITERATIONS = 60
"""Iterations of the 2-D outline fit."""

OUTLINE_MIN_TURN_DEG = 0.5
"""An outline turn smaller than this is not applied (the outline fit then only shifts): the scan's
edge (sampling, occlusion across the rim) gives the turn to a few tenths of a degree only, the
surface fit of a curved plate far better; the outline corrects the gross turns of the best fit."""

OUTLINE_MAX_TURN_DEG = 15.0
"""Largest turn the outline fit may apply (beyond it the fit is rejected)."""

OUTLINE_EDGE_SPACINGS = 3.0
"""Scan points within this many point spacings of the scan's convex outline are its edge candidates."""

OUTLINE_PIECE_SPACINGS = 8.0
"""Length of the pieces an outline edge is cut into for the edge fit, in point spacings."""

OUTLINE_EDGE_QUANTILE = 0.1
"""The scan's edge along a piece: this low quantile of its points' distances inside the outline."""

OUTLINE_BAND_SPACINGS = (4.0, 0.6)
"""Band (in point spacings) around the outer pieces' edge within which a piece is used: it
narrows from the first to the second value over the iterations of the edge fit."""

OUTLINE_ROUNDS = 2
"""Rounds of the outline fit and the plane removal (a tilt moves a curved plate's edge a little)."""

OUTLINE_MAX_SHIFT = 0.1
"""Largest in-plane shift the outline fit may apply, as a fraction of the plate length."""

POINT_STAGE_POINTS = 3000
"""Scan points used by the point-to-point stage (a seeded subsample)."""

TRIM_FRACTION = 0.05
"""Worst pairs dropped in each ICP iteration (outliers, the scan's edge beyond the design)."""

START_POINTS = 2000
"""Scan points used to score each principal-axes start by a converged ICP (a seeded subsample)."""

START_ITERATIONS = 40
"""ICP iterations (per stage) run from each principal-axes start before it is scored."""

HELD_TURN_STEP_DEG = 15.0
"""Step of the sweep of turns about the normal for the starts held at the reference mark."""

HELD_MAX_RMS_FRACTION = 0.05
"""A start held at the mark is taken when its points lie this close (RMS, fraction of the design's
length) to the design: a mark picked in the wrong place holds the scan off the design."""

MARK_HOLD_ROUNDS = 5
"""Rounds of a start fit with the reference mark held at its place (see :func:`_held_fit`)."""

TIE_RATIO = 1.25
"""Two starts whose converged RMS are within this factor are a tie (a nearly symmetric plate)."""

MARK_RADIUS_FRACTION = 0.1
"""A start agrees with the reference mark when it puts the mark within this fraction of the
design's length of the mark's place on the design."""


@dataclass(frozen=True, eq=False)
class Comparison:
    """The result of :func:`compare`. Lengths in mm.

    Attributes
    ----------
    rms_mm, max_abs_mm, mean_mm, std_mm : float
        Statistics of the inlier deviations, point by point (scanner noise included).
    form_rms_mm, form_max_abs_mm : float
        The same of the form deviation: the plate's deviation with the scanner's point
        noise averaged out by a local plane through each point's ``FORM_NEIGHBOURS``
        nearest inliers. The tolerance decision (:attr:`in_tolerance`) uses
        ``form_max_abs_mm``: a smooth steel plate has no 1 mm bumps 20 mm wide, its scan
        has (0.3 mm noise gives about +-1.2 mm extremes over 15 000 points).
    within_tolerance_pct : float
        Percent of the inliers with ``|deviation| <= tolerance_mm``.
    tolerance_mm, offset_mm : float
        As given.
    histogram_edges_mm : (b + 1,) float
    histogram_counts : (b,) int
        Histogram of the inlier deviations.
    transform : (4, 4) float
        Maps measured coordinates into design coordinates.
    registration : Registration
        The ICP report.
    deviation_mm : (n,) float
        Signed normal deviation of every measured point (NaN where the foot point search
        failed).
    inlier : (n,) bool
        Points used in the statistics.
    is_outlier : (n,) bool
        Points flagged as outliers (off the surface relative to their neighbours).
    is_outside : (n,) bool
        Points whose foot point is outside the design plate (or did not converge).
    measured_in_design : (n, 3) float
        The measured points moved into design coordinates.
    measured_uv_mm : (n, 2) float
        Their foot points' (u, v) in the design's local frame (for maps).
    design_frame : LocalFrame
        The design's local frame (u, v, n rows, as :func:`mppf.geometry.frame.fit_frame` gives it).
    normal_sign : float
        +1 when positive deviations lie on the frame's +n side, -1 when on its -n side
        (the normal was turned to point up in press coordinates).
    design_uv_mm : (m, 2) float
        The design points in that frame (for the outline of maps).
    design_fit_rms_mm : float
        RMS residual of the surface fitted to the design points.
    form_deviation_mm : (n,) float
        The form deviation of every inlier and of every trim-margin point that is not an
        outlier (NaN elsewhere; the margin points' are not in the form statistics).
    punch_deviation_mm : (rows, cols) float or None
        Deviation of the plate at each punch along press z (the stroke direction):
        positive = plate above the design. NaN where the punch is off the plate.
    punch_normal_deviation_mm : (rows, cols) float or None
        The same along the design normal.
    punch_interpolated : (rows, cols) bool or None
        Punches without measured points nearby (occlusion) whose value is interpolated.
    notes : list of str
    margin_mm : float
        Width of the trim margin (excess band around the design outline), as given.
    in_margin : (n,) bool
        Points whose foot point lies in the trim margin: beyond the design's convex
        outline, within the outline grown by ``margin_mm``. Measured, used for the punch
        deviations, not in the statistics (nor in ``inlier`` or ``is_outside``). All False
        when ``margin_mm`` is 0; default (None given): all False.
    """

    rms_mm: float
    max_abs_mm: float
    mean_mm: float
    std_mm: float
    within_tolerance_pct: float
    tolerance_mm: float
    offset_mm: float
    histogram_edges_mm: np.ndarray
    histogram_counts: np.ndarray
    transform: np.ndarray
    registration: Registration
    deviation_mm: np.ndarray
    inlier: np.ndarray
    is_outlier: np.ndarray
    is_outside: np.ndarray
    measured_in_design: np.ndarray
    measured_uv_mm: np.ndarray
    design_frame: LocalFrame
    normal_sign: float
    design_uv_mm: np.ndarray
    design_fit_rms_mm: float
    form_rms_mm: float = float("nan")
    form_max_abs_mm: float = float("nan")
    form_deviation_mm: np.ndarray | None = None
    punch_deviation_mm: np.ndarray | None = None
    punch_normal_deviation_mm: np.ndarray | None = None
    punch_interpolated: np.ndarray | None = None
    notes: list[str] = field(default_factory=list)
    margin_mm: float = 0.0
    in_margin: np.ndarray | None = None

    def __post_init__(self):
        if self.in_margin is None:
            object.__setattr__(self, "in_margin", np.zeros(self.deviation_mm.shape[0], dtype=bool))

    @property
    def n_points(self) -> int:
        """Number of measured points."""
        return int(self.deviation_mm.shape[0])

    @property
    def n_inliers(self) -> int:
        """Points in the statistics."""
        return int(self.inlier.sum())

    @property
    def in_tolerance(self) -> bool:
        """Largest absolute form deviation within the tolerance (see ``form_max_abs_mm``)."""
        return bool(self.form_max_abs_mm <= self.tolerance_mm)

    def to_dict(self) -> dict:
        """JSON-able summary: statistics, transform (4x4 lists), histogram, registration, punches."""
        doc = {
            "rms_mm": self.rms_mm,
            "max_abs_mm": self.max_abs_mm,
            "mean_mm": self.mean_mm,
            "std_mm": self.std_mm,
            "within_tolerance_pct": self.within_tolerance_pct,
            "form_rms_mm": self.form_rms_mm,
            "form_max_abs_mm": self.form_max_abs_mm,
            "tolerance_mm": self.tolerance_mm,
            "offset_mm": self.offset_mm,
            "in_tolerance": self.in_tolerance,
            "n_points": self.n_points,
            "n_inliers": self.n_inliers,
            "n_outliers": int(self.is_outlier.sum()),
            "n_outside": int(self.is_outside.sum()),
            "margin_mm": self.margin_mm,
            "n_margin": int(self.in_margin.sum()),
            "inlier_fraction": self.n_inliers / max(self.n_points, 1),
            "transform": tf_to_list(self.transform),
            "histogram": {"edges_mm": self.histogram_edges_mm.tolist(), "counts": self.histogram_counts.tolist()},
            "design_fit_rms_mm": self.design_fit_rms_mm,
            "registration": self.registration.to_dict(),
            "notes": list(self.notes),
        }
        if self.punch_deviation_mm is not None:
            doc["punch_deviation_mm"] = _nan_to_none(self.punch_deviation_mm)
            doc["punch_normal_deviation_mm"] = _nan_to_none(self.punch_normal_deviation_mm)
            doc["punch_interpolated"] = self.punch_interpolated.tolist()
        return doc


def _nan_to_none(grid: np.ndarray) -> list:
    return [[None if not np.isfinite(v) else float(v) for v in row] for row in grid]


def compare(
    design_points,
    measured_points,
    *,
    tolerance_mm: float = 2.5,
    offset_mm: float = 0.0,
    design_faces=None,
    punch_xy_mm=None,
    tf_press_design=None,
    bins: int | np.ndarray = 30,
    punch_radius_mm: float | None = None,
    rotation_hint=None,
    reference_mark=None,
    fit_outline: bool | None = None,
    margin_mm: float = 0.0,
) -> Comparison:
    """Register a scan onto its design and measure the deviation of every point.

    Parameters
    ----------
    design_points : (m, 3) float, mm
        The design plate (mid-surface), design coordinates.
    measured_points : (n, 3) float, mm
        The scan, in any pose.
    tolerance_mm : float
        Allowed absolute deviation.
    offset_mm : float
        The skin that was measured, as a normal offset of the design: ``+t/2`` top
        skin, ``0`` mid-surface, ``-t/2`` bottom skin ("top" = +normal side, see the
        module docstring).
    design_faces : (k, 3) int, optional
        Design mesh triangles (a stricter fold-over check of the design).
    punch_xy_mm : (rows, cols, 2) float, optional
        Punch axis positions (x, y) in press coordinates; needs ``tf_press_design``.
    tf_press_design : (4, 4) float, optional
        Maps design into press coordinates (the job's); also orients the normal up.
    bins : int or (b + 1,) float
        Histogram bins: a count (symmetric about 0) or the edges in mm.
    punch_radius_mm : float, optional
        Radius around a punch axis whose points give its deviation (default: 0.45 of
        the punch pitch).
    rotation_hint : (3, 3) or (4, 4) float, optional
        Rough rotation from measured into design coordinates (within about 45 deg), e.g.
        ``invert_tf(tf_press_design)`` when the scanner's axes are the press's. It picks
        which of the four principal-axes starts to use, so that a nearly symmetric plate
        is not registered turned by a half turn. Used only to break a tie: when the
        best two of the four starts, each scored by a converged robust ICP, fit within
        ``TIE_RATIO`` of each other. Default: the best fitting start.
    reference_mark : pair of (3,) float, optional
        ``(measured_xyz, design_xyz)``: where the plate's reference-corner mark is in the
        scan, and where that corner is on the design. Of the four starts, only those that
        put the mark within ``MARK_RADIUS_FRACTION`` of the design's length of its place
        are used (the best fitting of them); this settles the half turns of nearly
        symmetric plates (see ``docs/compare.md``, "Which way round").
    fit_outline : bool, optional
        After the ICP, set the in-plane position and turn by the plate's outline (the
        scan's edge against the design's) and then the out-of-plane position by the
        deviations (see :func:`_outline_refit`). Default: on when ``punch_xy_mm`` is
        given (on the press the outline places the plate, and the punch deviations must
        be where the punches are), off otherwise (pure best fit).
    margin_mm : float
        Width (mm, >= 0) of the trim margin the scanned plate still carries around the
        design's outline. The registration target, the size check and the outline fit use
        the design's convex outline grown by it (:func:`offset_convex`); points in
        the band (``Comparison.in_margin``) are measured against the design surface's
        extension past its edge and give the deviations of the punches under the margin,
        but are left out of every statistic (the tolerance is on the net plate). Default
        0: no margin.

    Returns
    -------
    Comparison

    Raises
    ------
    InputError
        Bad options or shapes.
    GeometryError
        Too few points, a design that is not a plate, or a scan that does not match the
        design (registration failed or most points far from it).
    """
    # 0. inputs
    design = as_points(design_points, name="design points")
    measured = as_points(measured_points, name="measured points")
    _check_options(tolerance_mm, offset_mm, measured, punch_xy_mm, tf_press_design)
    margin_mm = _check_margin(margin_mm)

    # 1. the design surface, its normal oriented (up in press coordinates when known)
    fitted = fit_plate(design, kind="spline", faces=design_faces, source="design")
    frame, surface = fitted.frame, fitted.surface
    sign = _normal_sign(frame, tf_press_design)
    design_local = fitted.frame.to_local(design)
    uv_d = design_local[:, :2]
    _check_size(uv_d, measured, margin_mm)

    # 2. the design moved to the measured skin, sampled densely (over the outline grown by the margin)
    target = _dense_skin(fitted, uv_d, sign, offset_mm, margin_mm)

    # 3. robust registration of the scan onto the design skin, and
    # 4. signed normal deviation of every point (foot points on the design surface)
    init, start_note = _choose_start(measured, target, rotation_hint, reference_mark, float(np.ptp(uv_d, axis=0).max()))
    reg, moved, feet, deviation, outside, in_margin, reg_note = _register(measured, target, fitted, uv_d, sign,
                                                                          offset_mm, init, margin_mm)
    reg_note = f"{start_note}; {reg_note}"
    transform = reg.tf
    if fit_outline is None:
        fit_outline = punch_xy_mm is not None
    if fit_outline:
        transform, note = _outline_refit(fitted, uv_d, measured, transform, sign, offset_mm, margin_mm,
                                         tf_press_design)
        reg_note = f"{reg_note}; {note}"
        moved, feet, deviation, outside, in_margin = _deviate(measured, transform, fitted, uv_d, sign, offset_mm,
                                                              margin_mm)
    uv = np.asarray(feet.uv, dtype=float)
    _check_match(deviation, outside, tolerance_mm, reg, depth_mm=float(np.ptp(design_local[:, 2])))

    # 5. outliers relative to their neighbours (the margin's points are neighbours too)
    outlier = _outliers(uv, deviation, ~outside)
    inlier = ~outside & ~outlier & ~in_margin
    measured_ok = ~outside & ~outlier  # net and margin: the punch deviations
    if inlier.sum() < MIN_POINTS:
        raise GeometryError(f"only {int(inlier.sum())} of {len(inlier)} measured points are usable "
                            f"({int(outlier.sum())} outliers, {int(outside.sum())} outside the design, "
                            f"{int(in_margin.sum())} in the trim margin)",
                            hint="check the scan: it should cover most of the plate")

    # 6. statistics, histogram and punch deviations
    d = deviation[inlier]
    form = np.full(deviation.shape[0], np.nan)
    form[inlier] = _local_plane(uv[inlier], d, FORM_NEIGHBOURS, leave_out=False, robust_passes=1)
    margin_ok = measured_ok & in_margin
    if margin_ok.any():  # for maps only: the net plate's form values above do not see the margin
        form_all = _local_plane(uv[measured_ok], deviation[measured_ok], FORM_NEIGHBOURS, leave_out=False,
                                robust_passes=1)
        form[margin_ok] = form_all[in_margin[measured_ok]]
    edges = _bin_edges(d, tolerance_mm, bins)
    counts, _ = np.histogram(np.clip(d, edges[0], edges[-1]), bins=edges)
    notes = [reg_note, f"{int(outlier.sum())} outlier(s) and {int(outside.sum())} point(s) outside the design "
             "left out of the statistics"]
    if margin_mm > 0:
        notes.append(f"{int(in_margin.sum())} point(s) in the trim margin ({margin_mm:g} mm) left out of the "
                     "statistics")
    punch = punch_n = punch_interp = None
    if punch_xy_mm is not None:
        n_z = apply_rotation(np.asarray(tf_press_design, dtype=float) @ fitted.frame.tf_world_local,
                             surface.normals(uv[:, 0], uv[:, 1]))[:, 2] * sign
        foot_press = apply_tf(np.asarray(tf_press_design, dtype=float) @ fitted.frame.tf_world_local,
                              np.asarray(feet.xyz, dtype=float))
        design_press = apply_tf(tf_press_design, design)
        punch, punch_n, punch_interp = _punch_deviation(
            np.asarray(punch_xy_mm, dtype=float), foot_press[measured_ok, :2], deviation[measured_ok],
            np.maximum(n_z[measured_ok], 0.2), design_press[:, :2], punch_radius_mm, margin_mm)
        notes.append(f"punch deviations: {int(np.isfinite(punch).sum())} punches on the plate, "
                     f"{int(punch_interp.sum())} interpolated across gaps in the scan")
    return Comparison(
        rms_mm=float(np.sqrt(np.mean(d**2))),
        max_abs_mm=float(np.max(np.abs(d))),
        mean_mm=float(np.mean(d)),
        std_mm=float(np.std(d)),
        within_tolerance_pct=float(100.0 * np.mean(np.abs(d) <= tolerance_mm)),
        tolerance_mm=float(tolerance_mm),
        offset_mm=float(offset_mm),
        histogram_edges_mm=edges,
        histogram_counts=counts,
        transform=transform,
        registration=reg,
        deviation_mm=deviation,
        inlier=inlier,
        is_outlier=outlier,
        is_outside=outside,
        measured_in_design=moved,
        measured_uv_mm=uv,
        design_frame=frame,
        normal_sign=sign,
        design_uv_mm=uv_d,
        design_fit_rms_mm=float(fitted.rms_mm),
        form_rms_mm=float(np.sqrt(np.mean(form[inlier] ** 2))),
        form_max_abs_mm=float(np.max(np.abs(form[inlier]))),
        form_deviation_mm=form,
        punch_deviation_mm=punch,
        punch_normal_deviation_mm=punch_n,
        punch_interpolated=punch_interp,
        notes=notes,
        margin_mm=margin_mm,
        in_margin=in_margin,
    )


def _dense_skin(fitted, uv_design: np.ndarray, sign: float, offset_mm: float, margin_mm: float = 0.0) -> np.ndarray:
    """The design skin sampled densely from its fitted surface (world coordinates).

    About ``DENSE_POINTS`` points on a square grid over the design's convex outline grown
    by ``margin_mm`` (:func:`offset_convex`; beyond the design's edge the spline
    surface continues as its tangent plane there, see :class:`mppf.geometry.surface.SplineSurface`):
    a dense target makes point-to-point ICP nearly a point-to-surface distance, without
    the bias of a coarse design grid.
    """
    outline = offset_convex(uv_design[ConvexHull(uv_design).vertices], margin_mm)
    lo, hi = outline.min(axis=0), outline.max(axis=0)
    step = max(float(np.sqrt(np.prod(hi - lo) / DENSE_POINTS)), 1e-6)
    uu, vv = np.meshgrid(np.arange(lo[0], hi[0] + 1e-9, step), np.arange(lo[1], hi[1] + 1e-9, step))
    uv = np.column_stack([uu.ravel(), vv.ravel()])
    uv = uv[PolygonPath(outline).contains_points(uv, radius=1e-9)]
    w = fitted.surface.evaluate(uv[:, 0], uv[:, 1])
    local = np.column_stack([uv, w]) + (sign * offset_mm) * fitted.surface.normals(uv[:, 0], uv[:, 1])
    return fitted.frame.to_world(local)


def _deviate(measured, tf, fitted, uv_design, sign: float, offset_mm: float, margin_mm: float = 0.0):
    """Moved points, foot points, signed deviations, the outside and the trim-margin masks for a transform.

    ``outside``: the foot point failed or lies beyond the outline grown by ``margin_mm``;
    ``in_margin``: not outside, but beyond the design's (net) convex outline; all False
    without a margin.
    """
    moved = apply_tf(tf, measured)
    feet = foot_points(fitted.surface, fitted.frame.to_local(moved))
    distance = np.asarray(feet.distance_mm, dtype=float)
    deviation = np.where(np.isfinite(distance), sign * distance - offset_mm, np.nan)
    uv = np.asarray(feet.uv, dtype=float)
    outside = (~np.asarray(feet.converged, dtype=bool) | ~np.isfinite(deviation)
               | _outside(uv_design, uv, margin_mm))
    in_margin = np.zeros(len(outside), dtype=bool)
    if margin_mm > 0:
        net = PolygonPath(uv_design[ConvexHull(uv_design).vertices])
        in_margin = ~outside & ~net.contains_points(uv, radius=1e-9)
    return moved, feet, deviation, outside, in_margin


def _outline_refit(fitted, uv_design, measured, tf, sign: float, offset_mm: float, margin_mm: float = 0.0,
                   tf_press_design=None):
    """Re-place a registered scan by its outline (in-plane) and its deviations (out of plane).

    Best-fit registration trades shape errors against rigid moves: a plate formed with a
    few mm of error fits best turned and shifted, so that the deviations land beside the
    punches that caused them. On the press the plate's outline fixes it in the plane and
    the strokes act along press z; so here, in the press's coordinates when
    ``tf_press_design`` is given (else in the design's frame, its normal as "z"):

    1. seen along z, the scan's edge points (those within 1.5 point spacings of the scan's
       convex outline; gaps from occlusion are bridged and skipped) are fitted to the
       outline of the design skin that was measured (its convex outline seen along z,
       grown by ``margin_mm``: a scan that still carries its trim margin,
       :func:`offset_convex`) by 2-D point-to-segment ICP (trimmed 10 %): a turn
       about z and a shift across it. A turn below ``OUTLINE_MIN_TURN_DEG`` is not
       applied (the fit is then redone as a shift only);
    2. then the best plane ``dz ~ a + b x + c y`` (robust) of the deviations along z over
       the net plate's points (the margin's left out) is removed by a shift along z and
       small tilts about the plate's centre;
    3. both steps are repeated (``OUTLINE_ROUNDS``): a tilt moves a curved plate's edge a
       little across z.

    Seen from above the press is the view of the planner (the plate's outline as cut,
    :func:`mppf.planning.plan.plan_job`) and of the strokes, so the punch deviations come out where
    the punches are; a view along the design's own normal would shift the outline of a
    plate that sits tilted on the press by its depth times the tilt.

    Returns the new measured -> design transform and a note. Falls back to ``tf`` when the
    scan shows too little edge or the outline fit wants an implausible move.
    """
    frame = fitted.frame
    if tf_press_design is None:
        view = frame.tf_local_world  # design world -> the design's frame
        corners = offset_convex(uv_design[ConvexHull(uv_design).vertices], margin_mm)
    else:
        press_design = np.asarray(tf_press_design, dtype=float)
        # the measured skin of the net design, seen from above the press
        local = np.column_stack([uv_design, fitted.surface.evaluate(uv_design[:, 0], uv_design[:, 1])])
        skin = apply_tf(press_design, frame.to_world(
            local + (sign * offset_mm) * fitted.surface.normals(uv_design[:, 0], uv_design[:, 1])))
        centre = np.eye(4)
        centre[:3, 3] = -skin.mean(axis=0)  # turns and tilts about the plate's centre
        view = centre @ press_design
        xy = skin[:, :2] + centre[:2, 3]
        corners = offset_convex(xy[ConvexHull(xy).vertices], margin_mm)
    unview = np.linalg.inv(view)
    seg_a, seg_b = corners, np.roll(corners, -1, axis=0)
    size_mm = float(np.ptp(uv_design, axis=0).max())
    turns, shifts = [], []
    for _ in range(OUTLINE_ROUNDS):
        xy = apply_tf(view @ tf, measured)[:, :2]
        spacing = float(np.median(cKDTree(xy).query(xy, k=2)[0][:, 1]))
        edge = _distance_to_polygon(xy, xy[ConvexHull(xy).vertices]) < OUTLINE_EDGE_SPACINGS * spacing
        if edge.sum() < 20:
            return tf, "outline fit skipped: too few edge points in the scan"
        points = xy[edge]
        total = _fit_outline_2d(points, seg_a, seg_b, True, spacing)
        if abs(float(np.degrees(np.arctan2(total[1, 0], total[0, 0])))) < OUTLINE_MIN_TURN_DEG:
            total = _fit_outline_2d(points, seg_a, seg_b, False, spacing)
        turn_deg = float(np.degrees(np.arctan2(total[1, 0], total[0, 0])))
        shift_mm = float(np.hypot(*total[:2, 2]))
        if abs(turn_deg) > OUTLINE_MAX_TURN_DEG or shift_mm > OUTLINE_MAX_SHIFT * size_mm:
            return tf, (f"outline fit skipped: it wanted a turn of {turn_deg:.1f} deg and a shift of "
                        f"{shift_mm:.0f} mm")
        turns.append(turn_deg)
        shifts.append(shift_mm)
        in_plane = np.eye(4)
        in_plane[:2, :2] = total[:2, :2]
        in_plane[:2, 3] = total[:2, 2]
        tf = unview @ in_plane @ view @ tf
        # out of plane: remove the deviations' robust best plane (along z) by a shift and two tilts
        for _ in range(3):
            moved, feet, deviation, outside, in_margin = _deviate(measured, tf, fitted, uv_design, sign, offset_mm,
                                                                  margin_mm)
            fuv = np.asarray(feet.uv, dtype=float)
            use = ~outside & ~in_margin
            # the deviation along the normal, as a height along z: d / n_z (n_z of the "up" normal)
            n_z = apply_rotation(view @ frame.tf_world_local, fitted.surface.normals(fuv[use, 0], fuv[use, 1]))[:, 2]
            at = apply_tf(view, moved[use])[:, :2]
            coef = _robust_plane(at, deviation[use] / np.maximum(sign * n_z, 0.2))
            a, b, c = coef
            lift = make_tf(Rotation.from_rotvec([-c, b, 0.0]).as_matrix(), [0.0, 0.0, -a])
            tf = unview @ lift @ view @ tf
    seen = "from above the press" if tf_press_design is not None else "along the design's normal"
    return tf, (f"outline fit ({seen}): turned {sum(turns):+.2f} deg and shifted {shifts[0]:.1f} mm in the plane"
                + (f", then {', '.join(f'{s:.1f}' for s in shifts[1:])} mm" if len(shifts) > 1 else ""))


def _fit_outline_2d(points, seg_a, seg_b, turn: bool, spacing_mm: float) -> np.ndarray:
    """(3, 3) 2-D transform fitting a scan's edge to the outline segments (turn + shift, or shift only).

    A scan's edge is not its outermost points one by one: the scanner samples the plate
    at some spacing, so along an edge the outermost points stand up to a spacing in, and
    a hidden stretch (a clamp, a shadow) leaves only points further in. So each outline
    edge is cut into pieces about ``OUTLINE_PIECE_SPACINGS`` point spacings long, and the
    scan's edge along a piece is the low ``OUTLINE_EDGE_QUANTILE`` of its points' insets
    (distance inside the outline): the envelope of the points, not their mean. Pieces
    whose envelope lies far from the others' (a hidden stretch, the rim of an occlusion)
    are left out; the common inset of the rest (the sampling's) is removed; the pieces'
    edge points are then fitted to the outline by least squares, weighted by their length.
    """
    inward = _inward_normals(seg_a, seg_b)
    lengths = np.linalg.norm(seg_b - seg_a, axis=1)
    piece_mm = max(OUTLINE_PIECE_SPACINGS * spacing_mm, 1e-6)
    pieces_per_seg = np.maximum(np.ceil(lengths / piece_mm).astype(int), 1)
    first_piece = np.concatenate([[0], np.cumsum(pieces_per_seg)[:-1]])
    total = np.eye(3)
    rough, fine = True, 0
    for _ in range(OUTLINE_ITERATIONS):
        moved = points @ total[:2, :2].T + total[:2, 2]
        foot, index = _closest_on_segments(moved, seg_a, seg_b, with_index=True)
        inset = np.einsum("nd,nd->n", moved - foot, inward[index])  # > 0 inside the outline
        along = np.linalg.norm(foot - seg_a[index], axis=1) / np.maximum(lengths[index], 1e-12)
        piece = first_piece[index] + np.minimum((along * pieces_per_seg[index]).astype(int), pieces_per_seg[index] - 1)
        dst, depth, normal, weight = [], [], [], []
        for k in np.unique(piece):
            members = piece == k
            if members.sum() < 3:
                continue
            seg = int(index[members][0])
            dst.append(foot[members].mean(axis=0))  # on the (straight) segment
            depth.append(float(np.quantile(inset[members], OUTLINE_EDGE_QUANTILE)))  # the scan's edge there
            normal.append(inward[seg])
            weight.append(float(np.ptp(along[members]) * lengths[seg]) + spacing_mm)
        if len(dst) < 4:
            break
        dst, depth, normal, weight = np.asarray(dst), np.asarray(depth), np.asarray(normal), np.asarray(weight)
        src = dst + depth[:, None] * normal  # the scan's edge along each piece
        # the edge is the scan's envelope: once roughly placed (all pieces used), pieces standing
        # further in or out than most (their outer row of points missing, a hidden stretch, a
        # stray point) are left out, with a band that narrows from a few spacings to about
        # half a spacing around the outer quartile of the pieces' edges
        if rough:
            keep = np.ones(len(depth), dtype=bool)
        else:
            band = spacing_mm * max(OUTLINE_BAND_SPACINGS[1], OUTLINE_BAND_SPACINGS[0] * 0.7 ** fine)
            keep = np.abs(depth - float(np.quantile(depth, 0.25))) <= band
            fine += 1
        if keep.sum() < 4:
            break
        centre = float(np.median(depth[keep]))
        target = dst + centre * normal  # remove the sampling's common inset
        step = _rigid_2d(src[keep], target[keep], weight[keep])
        if not turn:
            step = np.eye(3)
            w = weight[keep] / weight[keep].sum()
            step[:2, 2] = ((target[keep] - src[keep]) * w[:, None]).sum(axis=0)
        total = step @ total
        small = np.hypot(*step[:2, 2]) < 1e-3 and abs(np.arctan2(step[1, 0], step[0, 0])) < 1e-7
        if rough and (small or np.hypot(*step[:2, 2]) < 0.05 * spacing_mm):
            rough = False  # roughly placed: from now on the envelope's outliers are left out
        elif small and fine > 6:
            break
    return total


def _inward_normals(seg_a: np.ndarray, seg_b: np.ndarray) -> np.ndarray:
    """Unit normals (k, 2) of a closed polygon's edges a -> b, pointing into the polygon."""
    ab = seg_b - seg_a
    area2 = float(np.sum(seg_a[:, 0] * seg_b[:, 1] - seg_b[:, 0] * seg_a[:, 1]))  # > 0: counter-clockwise
    left = np.column_stack([-ab[:, 1], ab[:, 0]]) * (1.0 if area2 > 0 else -1.0)
    return left / np.maximum(np.linalg.norm(left, axis=1, keepdims=True), 1e-12)


def _distance_to_polygon(points: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Distance (n,) of 2-D points to the boundary of a polygon given by its corners."""
    closest = _closest_on_segments(points, corners, np.roll(corners, -1, axis=0))
    return np.linalg.norm(points - closest, axis=1)


def _closest_on_segments(points: np.ndarray, seg_a: np.ndarray, seg_b: np.ndarray, with_index: bool = False):
    """Closest point (n, 2) on any of the segments a -> b (k, 2) for each 2-D point (and the segment's index)."""
    ab = seg_b - seg_a
    t = np.einsum("nkd,kd->nk", points[:, None, :] - seg_a[None], ab) / np.maximum(np.einsum("kd,kd->k", ab, ab),
                                                                                       1e-12)
    foot = seg_a[None] + np.clip(t, 0.0, 1.0)[..., None] * ab[None]
    best = np.argmin(np.linalg.norm(points[:, None, :] - foot, axis=2), axis=1)
    closest = foot[np.arange(len(points)), best]
    return (closest, best) if with_index else closest


def _rigid_2d(source: np.ndarray, target: np.ndarray, weight: np.ndarray | None = None) -> np.ndarray:
    """(3, 3) homogeneous 2-D rigid transform best mapping source onto target (weighted least squares)."""
    w = np.ones(len(source)) if weight is None else np.asarray(weight, dtype=float)
    w = w / w.sum()
    mu_s, mu_t = w @ source, w @ target
    u, _, vt = np.linalg.svd(((source - mu_s) * w[:, None]).T @ (target - mu_t))
    rot = vt.T @ u.T
    if np.linalg.det(rot) < 0:
        vt[-1] *= -1
        rot = vt.T @ u.T
    out = np.eye(3)
    out[:2, :2] = rot
    out[:2, 2] = mu_t - rot @ mu_s
    return out


def _robust_plane(uv: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(a, b, c) of values ~ a + b u + c v, refitted twice without the points beyond 3 MAD."""
    design = np.column_stack([np.ones(len(uv)), uv])
    keep = np.isfinite(values)
    coef = np.zeros(3)
    for _ in range(3):
        coef, *_ = np.linalg.lstsq(design[keep], values[keep], rcond=None)
        resid = values - design @ coef
        mad = np.median(np.abs(resid[keep] - np.median(resid[keep])))
        keep = np.isfinite(values) & (np.abs(resid) <= max(3.0 * 1.4826 * mad, 1e-6))
    return coef


def _as_rotation(rotation_hint) -> np.ndarray:
    hint = np.asarray(rotation_hint, dtype=float)
    if hint.shape not in ((3, 3), (4, 4)) or not np.all(np.isfinite(hint)):
        raise InputError(f"rotation_hint must be a (3, 3) rotation or a (4, 4) transform, got shape {hint.shape}")
    return hint[:3, :3]


def _as_mark(reference_mark) -> tuple[np.ndarray, np.ndarray]:
    try:
        measured, design = (np.asarray(p, dtype=float).reshape(3) for p in reference_mark)
    except (TypeError, ValueError):
        raise InputError("reference_mark must be a pair (measured_xyz, design_xyz) of 3 coordinates each",
                         hint="give the mark's position in the scan and the corner's on the design, mm") from None
    if not (np.all(np.isfinite(measured)) and np.all(np.isfinite(design))):
        raise InputError(f"reference_mark has NaN or infinite coordinates: {measured}, {design}")
    return measured, design


def _choose_start(measured, target, rotation_hint, reference_mark, length_mm: float):
    """The start of the registration (measured -> design) and a note saying how it was chosen.

    Each of the four principal-axes starts (:func:`mppf.registration.register.principal_candidates`) is
    run to convergence by a trimmed, Huber-weighted point-to-plane ICP on a subsample of
    the scan and scored by its RMS. A few ICP iterations do not tell a nearly symmetric
    plate from its half turn when the plate is still some mm off its design; the
    converged fits usually do. Then:

    - with ``reference_mark``, the best start among those that agree with the mark;
    - else the best start, unless the second best is within ``TIE_RATIO`` of it and a
      ``rotation_hint`` is given: then the one of the two nearest to the hint.
    """
    hint = None if rotation_hint is None else _as_rotation(rotation_hint)
    mark = None if reference_mark is None else _as_mark(reference_mark)
    candidates = principal_candidates(fit_frame(measured), fit_frame(target))
    fits, scores = [], []
    for start in candidates:
        tf, rms = _start_fit(measured, target, start)
        fits.append(tf)
        scores.append(rms)
    order = [int(i) for i in np.argsort(scores)]
    best, second = order[0], order[1]
    scored = ", ".join(f"{s:.2f}" for s in scores)
    if mark is not None:
        miss = [float(np.linalg.norm(apply_tf(tf, mark[0][None])[0] - mark[1])) for tf in fits]
        agree = [i for i in order if miss[i] <= MARK_RADIUS_FRACTION * length_mm]
        if agree:
            chosen = agree[0]
            how = "the reference mark" + (" (it overruled the best fit)" if chosen != best else "")
            return fits[chosen], (f"start: {how}; converged RMS of the four principal-axes starts {scored} mm, "
                                  f"mark {miss[chosen]:.0f} mm from its place")
        # the free fits slid away (a plate still far off its design fits a shifted, turned
        # design about as well): fit again from each start with the mark held at its place
        tree = cKDTree(target)
        sample = measured[np.random.default_rng(0).choice(len(measured), size=min(len(measured), START_POINTS),
                                                          replace=False)]
        held = [_held_fit(measured, target, start, mark, tree, sample)
                for start in _held_starts(target, candidates, mark, tree, sample)]
        held_scores = [rms for _, rms in held]
        chosen = int(np.argmin(held_scores))
        # a mark picked in the wrong place holds the scan off the design: not taken
        if held_scores[chosen] <= HELD_MAX_RMS_FRACTION * length_mm:
            return held[chosen][0], (
                f"start: the reference mark held in place (the free fits slid {min(miss):.0f} mm or more off it); "
                f"RMS of the {len(held)} best turns so held {', '.join(f'{v:.1f}' for v in held_scores)} mm")
        note = (f"start: no start puts the reference mark near its place (nearest {min(miss):.0f} mm): "
                "the best fit is used; check the mark")
        return fits[best], f"{note}; converged RMS {scored} mm"
    if hint is not None and scores[second] <= TIE_RATIO * scores[best] + 1e-9:
        turns = {i: rotation_angle_deg(fits[i][:3, :3] @ hint.T) for i in (best, second)}
        chosen = min(turns, key=turns.get)
        return fits[chosen], f"start: tie of the best two starts broken by the rotation hint; converged RMS {scored} mm"
    tie = " (a tie of the best two: nearly symmetric plate, no hint)" if scores[second] <= TIE_RATIO * scores[best] else ""
    return fits[best], f"start: best converged fit{tie}; converged RMS {scored} mm"


def _held_starts(target, candidates, mark, tree, sample, keep: int = 3) -> list[np.ndarray]:
    """Starts with the reference mark on its place: the ``keep`` best of a sweep of turns.

    The principal axes of a scan with hidden parts may be tens of degrees off the design's;
    so both ways up (the candidates' normal flipped or not), the scan is turned about the
    design's normal through the mark in steps of ``HELD_TURN_STEP_DEG`` and each pose is
    scored, without iterating, by :func:`_nearest_rms` of the scan's ``sample`` (clipped at
    a tenth of the design's size, so that a far corner does not rule). ``tree`` is the
    design skin's k-d tree.
    """
    normal = fit_frame(target).axes[2]
    clip = 0.1 * float(np.ptp(target, axis=0).max())
    poses, scores = [], []
    for base in (candidates[0], candidates[2]):  # the two ways up
        for turn in np.arange(0.0, 360.0, HELD_TURN_STEP_DEG):
            tf = make_tf(Rotation.from_rotvec(np.radians(turn) * normal).as_matrix() @ base[:3, :3], np.zeros(3))
            tf[:3, 3] = mark[1] - apply_tf(tf, mark[0][None])[0]
            poses.append(tf)
            scores.append(_nearest_rms(tree, sample, tf, clip))
    return [poses[i] for i in np.argsort(scores)[:keep]]


def _nearest_rms(tree, points, tf, clip: float = np.inf) -> float:
    """RMS distance (mm) of ``points`` moved by ``tf`` to their nearest design points, each clipped."""
    near, _ = tree.query(apply_tf(tf, points))
    return float(np.sqrt(np.mean(np.minimum(near, clip) ** 2)))


def _start_fit(measured, target, start) -> tuple[np.ndarray, float]:
    """A start converged by trimmed, Huber-weighted point-to-plane ICP on a subsample: (tf, RMS)."""
    reg = register_icp(measured, target, method="plane", init=start, trim_fraction=TRIM_FRACTION,
                       robust="huber", pin_outline=False, max_points=START_POINTS,
                       max_iterations=START_ITERATIONS)
    return reg.tf, reg.rms_mm


def _held_fit(measured, target, start, mark, tree, sample) -> tuple[np.ndarray, float]:
    """A start fitted with the reference mark held at its place: (tf, RMS distance of ``sample``).

    Point-to-point ICP on a subsample in ``MARK_HOLD_ROUNDS`` rounds, each followed by the
    shift that puts the mark (measured, design) back on its place: the best fit with the
    mark held (to within the few mm it was picked to). Scored by :func:`_nearest_rms`: a
    pose held off the design by the mark leaves points beyond the design's edge, whose
    point-to-plane distances can still be small.
    """
    tf = np.array(start, dtype=float)
    for _ in range(MARK_HOLD_ROUNDS):
        tf[:3, 3] += mark[1] - apply_tf(tf, mark[0][None])[0]
        reg = register_icp(measured, target, method="point", init=tf, trim_fraction=TRIM_FRACTION,
                           pin_outline=False, max_points=START_POINTS,
                           max_iterations=max(START_ITERATIONS // MARK_HOLD_ROUNDS, 1))
        tf = np.array(reg.tf, dtype=float)
    tf[:3, 3] += mark[1] - apply_tf(tf, mark[0][None])[0]
    return tf, _nearest_rms(tree, sample, tf)


def _register(measured, target, fitted, uv_design, sign: float, offset_mm: float, init="principal",
              margin_mm: float = 0.0):
    """Register in two stages, then deviate every point.

    1. Point-to-point ICP (principal-axes start, plain least squares) on the dense design
       skin: it keeps the scan centred on the plate even where the surface alone cannot
       fix the in-plane position (a cylinder's axis, a nearly flat plate).
    2. Point-to-plane ICP from there, trimmed and Huber-weighted: accurate along the
       normal, insensitive to outliers. It is kept unless it slid part of the scan off
       the design's edge (grossly different shapes), then stage 1 is used.

    The design's edge is its outline grown by ``margin_mm`` (the trim margin). ``init`` is
    "principal" (the best of the four principal-axes starts) or a start
    transform (:func:`_choose_start`).
    """
    stages = []
    for method, trim, robust, max_points, iterations in (("point", None, None, POINT_STAGE_POINTS, 40),
                                                         ("plane", TRIM_FRACTION, "huber", 30000, 100)):
        reg = register_icp(measured, target, method=method, init=init, trim_fraction=trim, robust=robust,
                           pin_outline=False, max_points=max_points, max_iterations=iterations)
        init = reg.tf
        stages.append((reg, *_deviate(measured, reg.tf, fitted, uv_design, sign, offset_mm, margin_mm)))
    point, plane = stages
    if plane[4].mean() <= point[4].mean() + OVERHANG_FRACTION:
        return (*plane, "registration: point-to-point, then point-to-plane (trimmed, Huber)")
    return (*point, f"registration: point-to-point only; point-to-plane left {100 * plane[4].mean():.0f} % of "
                    "the scan outside the design (the shapes differ much)")


def _check_options(tolerance_mm, offset_mm, measured, punch_xy_mm, tf_press_design) -> None:
    if not (np.isfinite(tolerance_mm) and tolerance_mm > 0):
        raise InputError(f"tolerance must be a positive length, got {tolerance_mm} mm")
    if not np.isfinite(offset_mm):
        raise InputError(f"skin offset must be finite, got {offset_mm} mm")
    if measured.shape[0] < MIN_POINTS:
        raise GeometryError(f"the scan has {measured.shape[0]} point(s), a comparison needs at least {MIN_POINTS}",
                            hint="check the scan export")
    if punch_xy_mm is not None:
        grid = np.asarray(punch_xy_mm, dtype=float)
        if grid.ndim != 3 or grid.shape[2] != 2:
            raise InputError(f"punch positions must have shape (rows, cols, 2), got {grid.shape}")
        if tf_press_design is None:
            raise InputError("punch deviations need tf_press_design (design -> press)",
                             hint="pass the job's tf_press_design")
    if tf_press_design is not None and np.asarray(tf_press_design, dtype=float).shape != (4, 4):
        raise InputError(f"tf_press_design must be 4x4, got {np.asarray(tf_press_design).shape}")


def _check_margin(margin_mm) -> float:
    """The trim margin as a float; InputError unless it is a finite length >= 0."""
    try:
        value = float(margin_mm)
    except (TypeError, ValueError):
        raise InputError(f"trim margin must be a length in mm, got {margin_mm!r}",
                         hint="give the width of the excess band around the design outline, e.g. 50") from None
    if not (np.isfinite(value) and value >= 0):
        raise InputError(f"trim margin must be a finite length >= 0 mm, got {margin_mm}",
                         hint="give the width of the excess band around the design outline, 0 for a net plate")
    return value


def _normal_sign(frame: LocalFrame, tf_press_design) -> float:
    """+1 or -1: the sign that makes the frame's normal point up in press coordinates (when known)."""
    if tf_press_design is None:
        return 1.0
    up = apply_rotation(np.asarray(tf_press_design, dtype=float), frame.axes[2:3])[0, 2]
    return 1.0 if up >= 0 else -1.0


def _outside(uv_design: np.ndarray, uv: np.ndarray, margin_mm: float = 0.0) -> np.ndarray:
    """Foot points outside the design: beyond its convex hull and away from its points.

    With a trim margin: beyond the hull grown by ``margin_mm`` (:func:`offset_convex`)
    and farther than ``margin_mm`` + 1.5 design spacings from the design's points.

    Parameters
    ----------
    uv_design : (m, 2) float, mm
        The design points in the design plane.
    uv : (n, 2) float, mm
        Foot points in the design plane.
    margin_mm : float
        Width of the trim margin (>= 0).

    Returns
    -------
    (n,) bool
    """
    tree = cKDTree(uv_design)
    spacing = float(np.median(tree.query(uv_design, k=2)[0][:, 1]))
    hull = ConvexHull(uv_design)
    beyond = ~PolygonPath(offset_convex(uv_design[hull.vertices], margin_mm)).contains_points(uv)
    far = tree.query(uv)[0] > 1.5 * max(spacing, 1e-9) + margin_mm
    return beyond & far


def _check_size(uv_design: np.ndarray, measured: np.ndarray, margin_mm: float = 0.0) -> None:
    """Raise GeometryError when the scan's length is out of proportion with the design's.

    A scan that still carries its trim margin may be up to ``SIZE_RATIO[1]`` times the
    design's length plus twice the margin.
    """
    design_mm = float(np.ptp(uv_design[:, 0]))
    scan_mm = float(np.ptp(fit_frame(measured).to_local(measured)[:, 0]))
    if not SIZE_RATIO[0] * design_mm <= scan_mm <= SIZE_RATIO[1] * (design_mm + 2.0 * margin_mm):
        raise GeometryError(
            f"the scan is {scan_mm:.0f} mm long, the design {design_mm:.0f} mm: not the same plate",
            hint="check the files and the --units (a scan in metres read as millimetres is 1000 times too small)")


def _check_match(deviation, outside, tolerance_mm: float, reg: Registration, depth_mm: float) -> None:
    """Raise GeometryError when the scan is evidently of another plate (or did not register).

    Another plate: more than half of the scan lies beyond the design's edge, or more than
    half lies farther from the design than ``max(10 tolerance, 25 mm, depth / 4)`` (a
    badly formed but right plate stays within a quarter of its design depth).
    """
    n = deviation.shape[0]
    if outside.mean() > 1.0 - MATCH_FRACTION:
        raise GeometryError(
            f"the scan does not match the design: {100 * outside.mean():.0f} % of the measured points lie "
            "outside the design plate after registration",
            hint="check that the scan and the design are of the same plate (and the --units)")
    gross_mm = max(10.0 * tolerance_mm, 25.0, 0.25 * depth_mm)
    near = np.abs(np.where(outside, np.inf, deviation)) <= gross_mm
    if near.sum() < MATCH_FRACTION * n:
        raise GeometryError(
            f"the scan does not match the design: only {100 * near.mean():.0f} % of the measured points lie "
            f"within {gross_mm:g} mm of it after registration (registration RMS {reg.rms_mm:.1f} mm)",
            hint="check that the scan and the design are of the same plate (and the --units)")


def _outliers(uv: np.ndarray, deviation: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Points whose deviation differs from a robust local plane through their neighbours'.

    For each point, a plane d = a + b u + c v is fitted to the deviations of its
    ``OUTLIER_NEIGHBOURS`` nearest neighbours (in the design plane, the point itself left
    out), reweighted twice to ignore neighbours that are outliers themselves. The
    differences from those planes have a robust sigma (1.4826 MAD); a point is an outlier
    beyond ``OUTLIER_SIGMAS`` sigma (and ``OUTLIER_FLOOR_MM``). The local plane follows
    smooth shape errors, even steep ones, so those are never flagged.
    """
    idx = np.flatnonzero(valid)
    out = np.zeros(deviation.shape[0], dtype=bool)
    if min(OUTLIER_NEIGHBOURS + 1, idx.size) < 8:
        return out
    dev = deviation[idx]
    diff = dev - _local_plane(uv[idx], dev, OUTLIER_NEIGHBOURS, leave_out=True, robust_passes=3)
    sigma = 1.4826 * np.median(np.abs(diff - np.median(diff)))
    out[idx] = np.abs(diff) > max(OUTLIER_SIGMAS * sigma, OUTLIER_FLOOR_MM)
    return out


def _local_plane(pts: np.ndarray, values: np.ndarray, k: int, *, leave_out: bool, robust_passes: int) -> np.ndarray:
    """Value at each point of a plane d = a + b u + c v fitted to its ``k`` nearest neighbours.

    Parameters
    ----------
    pts : (m, 2) float
        Positions (mm, design plane).
    values : (m,) float
        Deviations there.
    k : int
        Neighbours in each fit (the point itself not counted when ``leave_out``).
    leave_out : bool
        Leave the point itself out of its own fit (for outlier tests).
    robust_passes : int
        Passes of reweighting that drop neighbours beyond 3 local median deviations
        (1: plain least squares).

    Returns
    -------
    (m,) float
    """
    k = min(k + int(leave_out), pts.shape[0])
    _, nb = cKDTree(pts).query(pts, k=k)
    if leave_out:
        nb = nb[:, 1:]
    rel = pts[nb] - pts[:, None, :]                                   # (m, k, 2)
    scale = np.maximum(np.abs(rel).max(axis=(1, 2)), 1e-9)[:, None, None]
    design = np.concatenate([np.ones(rel.shape[:2] + (1,)), rel / scale], axis=2)  # (m, k, 3)
    near = values[nb]
    weight = np.ones_like(near)
    for _ in range(robust_passes):
        a = np.einsum("mki,mk,mkj->mij", design, weight, design) + 1e-9 * np.eye(3)
        b = np.einsum("mki,mk,mk->mi", design, weight, near)
        coef = np.linalg.solve(a, b[..., None])[..., 0]
        resid = near - np.einsum("mki,mi->mk", design, coef)
        spread = np.maximum(np.median(np.abs(resid), axis=1, keepdims=True), 1e-6)
        weight = (np.abs(resid) <= 3.0 * spread).astype(float)
    return coef[:, 0]


def _bin_edges(d: np.ndarray, tolerance_mm: float, bins) -> np.ndarray:
    if np.ndim(bins) == 0:
        count = int(bins)
        if count < 1:
            raise InputError(f"histogram bins must be at least 1, got {bins}")
        half = max(float(np.max(np.abs(d))) if d.size else 0.0, tolerance_mm) * 1.05
        return np.linspace(-half, half, count + 1)
    edges = np.asarray(bins, dtype=float)
    if edges.ndim != 1 or edges.size < 2 or np.any(np.diff(edges) <= 0):
        raise InputError("histogram edges must be an increasing 1-D array of at least 2 values")
    return edges


def _punch_deviation(punch_xy, xy, deviation, n_z, design_xy, radius_mm, margin_mm: float = 0.0):
    """Median deviation near each punch axis; interpolated where the scan has a gap.

    Parameters
    ----------
    punch_xy : (rows, cols, 2) float, mm
        Punch axes in press coordinates.
    xy : (p, 2) float, mm
        Press (x, y) of the foot points of the measured points used (net and margin).
    deviation, n_z : (p,) float
        Their normal deviations (mm) and the press-z components of the design normal.
    design_xy : (m, 2) float, mm
        The design points' press (x, y).
    radius_mm : float or None
        Radius around an axis whose points give its deviation (None: 0.45 pitch).
    margin_mm : float
        Trim margin: a punch is on the plate when its axis lies inside the convex outline
        of ``design_xy`` grown by it (:func:`offset_convex`).

    Returns (stroke-direction deviation, normal deviation, interpolated mask), each
    (rows, cols); NaN where the punch is off the plate.
    """
    rows, cols, _ = punch_xy.shape
    flat = punch_xy.reshape(-1, 2)
    if radius_mm is None:
        pitch = cKDTree(flat).query(flat, k=2)[0][:, 1] if flat.shape[0] > 1 else np.array([100.0])
        radius_mm = 0.45 * float(np.median(pitch))
    hull = ConvexHull(design_xy)
    on_plate = PolygonPath(offset_convex(design_xy[hull.vertices], margin_mm)).contains_points(flat)
    normal = np.full(flat.shape[0], np.nan)
    vertical = np.full(flat.shape[0], np.nan)
    for i, near in enumerate(cKDTree(xy).query_ball_point(flat, radius_mm)):
        if on_plate[i] and len(near) >= 3:
            normal[i] = np.median(deviation[near])
            vertical[i] = np.median(deviation[near] / n_z[near])
    measured = np.isfinite(normal)
    gap = on_plate & ~measured
    if gap.any() and measured.sum() >= 3:
        # smooth fill: a thin-plate spline through the measured punch values
        for values in (normal, vertical):
            spline = RBFInterpolator(flat[measured], values[measured], kernel="thin_plate_spline", smoothing=0.1)
            values[gap] = spline(flat[gap])
    return vertical.reshape(rows, cols), normal.reshape(rows, cols), gap.reshape(rows, cols)
