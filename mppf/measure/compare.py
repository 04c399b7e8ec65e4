"""Compare a measured (scanned) plate with its design: register, deviate, summarise.

The steps of :func:`compare` (the math is in ``docs/compare.md``):

1. Fit the design surface: the design's own frame (best-fit plane) and a bicubic
   B-spline height field ``w = D(u, v)`` (:func:`mppf.geometry.surface.fit_plate`).
2. Offset the design to the measured skin: the design file is the mid-surface, a scanner
   sees a skin; ``offset_mm`` moves the design along its normal (``+t/2`` for the top skin)
   (:class:`mppf.measure.deviations.DesignSkin`). The skin, sampled densely, is the
   registration target, built once (:func:`mppf.registration.target.build_target`).
3. Register the scan onto it: the start from the principal axes, converged and settled by
   a reference mark or a rotation hint (:mod:`mppf.registration.scan_start`); then
   point-to-point ICP (keeps the scan centred on the plate), then point-to-plane ICP with
   trimmed, Huber-weighted pairs (accurate along the normal, ignores outliers); the point
   result is kept if the plane stage slid part of the scan off the design's edge
   (:func:`mppf.registration.register.register_icp`). With punch positions (the loop) the
   outline then fixes the in-plane pose and the deviations' best plane the out-of-plane
   pose (:func:`mppf.registration.outline_fit.refit_outline`).
4. Signed normal deviation of EVERY measured point: its foot point on the design surface
   (:func:`mppf.geometry.localize.foot_points`), distance along the design normal minus the offset.
   Positive = the measured plate lies on the +normal side of the design ("above").
5. Outliers: a point whose deviation differs from a robust local plane through its
   neighbours' deviations by more than a robust threshold (6 sigma of those differences,
   at least 0.5 mm) is flagged and left out of the statistics; so are points whose foot
   point falls outside the design (:mod:`mppf.measure.outliers`).
   Smooth shape errors (a bump, springback) are NOT outliers: their neighbours agree.
6. Statistics of the inliers (RMS, largest absolute, mean, percent within tolerance,
   histogram: :mod:`mppf.measure.statistics`) and, given the punch positions, the
   deviation at each punch (:mod:`mppf.measure.punches`).

A trim margin (``margin_mm``: the excess band the scanned plate still carries around the
net outline) grows the registration target, the size check and the outline fit by the
margin; points in the band are measured (against the design surface's extension past its
edge) and used for the punch deviations, but left out of the statistics.

Which way is "+normal": with ``tf_press_design`` the design normal pointing up in press
coordinates (+z); without it the normal of the design's frame (:mod:`mppf.geometry.frame`: the
side from which a curved plate looks concave, like a bowl on the press bed).
"""

from __future__ import annotations

import numpy as np

from mppf.core.errors import GeometryError, InputError
from mppf.core.transform import as_points
from mppf.core.validate import check_number, check_positive
from mppf.geometry.surface import fit_plate
from mppf.measure.deviations import DesignSkin, normal_sign
from mppf.measure.outliers import find_outliers, form_deviation
from mppf.measure.punches import punch_deviations
from mppf.measure.result import Comparison
from mppf.measure.statistics import statistics
from mppf.registration.outline_fit import refit_outline
from mppf.registration.register import Registration, register_icp
from mppf.registration.scan_start import choose_start
from mppf.registration.settings import ScanStages
from mppf.registration.target import build_target, prepare

MIN_POINTS = 30
"""Fewest measured points a comparison accepts."""

SIZE_RATIO = (0.3, 1.3)
"""Accepted range of the scan's length (largest in-plane extent) over the design's."""

MATCH_FRACTION = 0.5
"""At least this fraction of the measured points must lie near the design (else: wrong plate)."""

STAGES = ScanStages()
"""The two ICP stages of the scan's registration (defaults of :class:`~mppf.registration.settings.ScanStages`)."""


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
        ``ScanStart.tie_ratio`` of each other. Default: the best fitting start.
    reference_mark : pair of (3,) float, optional
        ``(measured_xyz, design_xyz)``: where the plate's reference-corner mark is in the
        scan, and where that corner is on the design. Of the four starts, only those that
        put the mark within ``ScanStart.mark_radius_fraction`` of the design's length of its place
        are used (the best fitting of them); this settles the half turns of nearly
        symmetric plates (see ``docs/compare.md``, "Which way round").
    fit_outline : bool, optional
        After the ICP, set the in-plane position and turn by the plate's outline (the
        scan's edge against the design's) and then the out-of-plane position by the
        deviations (:func:`mppf.registration.outline_fit.refit_outline`). Default: on when ``punch_xy_mm`` is
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
    margin_mm = _check_options(tolerance_mm, offset_mm, measured, punch_xy_mm, tf_press_design, margin_mm)

    # 1. the design surface, its normal oriented (up in press coordinates when known)
    fitted = fit_plate(design, kind="spline", faces=design_faces, source="design")
    skin = DesignSkin(fitted, design, normal_sign(fitted.frame, tf_press_design), offset_mm, margin_mm)
    scan = prepare(measured, "the scan")  # checked and framed once for every ICP run below
    _check_size(skin.uv, scan.frame.to_local(scan.points), margin_mm)

    # 2. the registration target: the skin sampled densely over the outline grown by the margin,
    #    with its k-d tree, frame and normals built once for every ICP run below
    target = build_target(skin.dense_points(), "the design skin")

    # 3. the start (principal axes, converged; the reference mark or the hint settle the turn),
    #    point-to-point then point-to-plane ICP, the signed deviation of every point
    init, start_note = choose_start(scan, target, rotation_hint, reference_mark, skin.length_mm)
    reg, dev, reg_note = _register(scan, target, skin, init)
    notes = [f"{start_note}; {reg_note}"]

    # 4. on the press the outline places the plate in the plane, the deviations out of it
    transform = reg.tf
    if fit_outline is None:
        fit_outline = punch_xy_mm is not None
    if fit_outline:
        transform, note = refit_outline(measured, transform, frame=fitted.frame, design_uv=skin.uv,
                                        skin_world=skin.at(skin.uv), tf_press_design=tf_press_design,
                                        margin_mm=margin_mm, heights=skin.heights(measured))
        notes[0] = f"{notes[0]}; {note}"
        dev = skin.deviate(measured, transform)
    _check_match(dev.deviation_mm, dev.outside, tolerance_mm, reg, depth_mm=float(np.ptp(skin.design_local[:, 2])))

    # 5. outliers relative to their neighbours (the margin's points are neighbours too)
    outlier = find_outliers(dev.uv, dev.deviation_mm, ~dev.outside)
    inlier = ~dev.outside & ~outlier & ~dev.in_margin
    measured_ok = ~dev.outside & ~outlier  # net and margin: the punch deviations
    _check_usable(inlier, outlier, dev)

    # 6. statistics, form deviation and punch deviations
    stats = statistics(dev.deviation_mm[inlier], tolerance_mm, bins)
    form = form_deviation(dev.uv, dev.deviation_mm, inlier, measured_ok, dev.in_margin)
    notes += _left_out(outlier, dev, margin_mm)
    punch = punch_n = punch_interp = None
    if punch_xy_mm is not None:
        punch, punch_n, punch_interp = punch_deviations(punch_xy_mm, tf_press_design, skin, dev, measured_ok, design,
                                                        punch_radius_mm)
        notes.append(f"punch deviations: {int(np.isfinite(punch).sum())} punches on the plate, "
                     f"{int(punch_interp.sum())} interpolated across gaps in the scan")
    return Comparison(
        rms_mm=stats.rms_mm, max_abs_mm=stats.max_abs_mm, mean_mm=stats.mean_mm, std_mm=stats.std_mm,
        within_tolerance_pct=stats.within_tolerance_pct, tolerance_mm=float(tolerance_mm),
        offset_mm=float(offset_mm), histogram_edges_mm=stats.histogram_edges_mm,
        histogram_counts=stats.histogram_counts, transform=transform, registration=reg,
        deviation_mm=dev.deviation_mm, inlier=inlier, is_outlier=outlier, is_outside=dev.outside,
        measured_in_design=dev.moved, measured_uv_mm=dev.uv, design_frame=fitted.frame, normal_sign=skin.sign,
        design_uv_mm=skin.uv, design_fit_rms_mm=float(fitted.rms_mm),
        form_rms_mm=float(np.sqrt(np.mean(form[inlier] ** 2))), form_max_abs_mm=float(np.max(np.abs(form[inlier]))),
        form_deviation_mm=form, punch_deviation_mm=punch, punch_normal_deviation_mm=punch_n,
        punch_interpolated=punch_interp, notes=notes, margin_mm=margin_mm, in_margin=dev.in_margin,
    )


def _register(scan, target, skin: DesignSkin, init, stages: ScanStages = STAGES):
    """Register in two stages, then deviate every point: (Registration, Deviation, note).

    1. Point-to-point ICP (plain least squares) on the dense design skin: it keeps the
       scan centred on the plate even where the surface alone cannot fix the in-plane
       position (a cylinder's axis, a nearly flat plate).
    2. Point-to-plane ICP from there, trimmed and Huber-weighted: accurate along the
       normal, insensitive to outliers. It is kept unless it slid part of the scan off
       the design's edge (grossly different shapes), then stage 1 is used.
    """
    point = register_icp(scan, target, method="point", init=init, pin_outline=False,
                         max_points=stages.point_points, max_iterations=stages.point_iterations)
    point_dev = skin.deviate(scan.points, point.tf)
    plane = register_icp(scan, target, method="plane", init=point.tf, trim_fraction=stages.trim_fraction,
                         robust=stages.robust, pin_outline=False, max_points=stages.plane_points,
                         max_iterations=stages.plane_iterations)
    plane_dev = skin.deviate(scan.points, plane.tf)
    if plane_dev.outside.mean() <= point_dev.outside.mean() + stages.overhang_fraction:
        return plane, plane_dev, "registration: point-to-point, then point-to-plane (trimmed, Huber)"
    return point, point_dev, (f"registration: point-to-point only; point-to-plane left "
                              f"{100 * plane_dev.outside.mean():.0f} % of the scan outside the design (the shapes "
                              "differ much)")


def _left_out(outlier, dev, margin_mm: float) -> list[str]:
    """Notes on the points left out of the statistics."""
    notes = [f"{int(outlier.sum())} outlier(s) and {int(dev.outside.sum())} point(s) outside the design "
             "left out of the statistics"]
    if margin_mm > 0:
        notes.append(f"{int(dev.in_margin.sum())} point(s) in the trim margin ({margin_mm:g} mm) left out of the "
                     "statistics")
    return notes


def _check_options(tolerance_mm, offset_mm, measured, punch_xy_mm, tf_press_design, margin_mm) -> float:
    """Check the options; return the trim margin as a float."""
    check_positive("tolerance", tolerance_mm, unit="mm")
    check_number("skin offset", offset_mm, unit="mm")
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
    return float(check_number("trim margin", margin_mm, low=0.0, unit="mm",
                              hint="give the width of the excess band around the design outline, 0 for a net plate"))


def _check_usable(inlier, outlier, dev) -> None:
    """Raise GeometryError when too few measured points are left for the statistics."""
    if inlier.sum() < MIN_POINTS:
        raise GeometryError(f"only {int(inlier.sum())} of {len(inlier)} measured points are usable "
                            f"({int(outlier.sum())} outliers, {int(dev.outside.sum())} outside the design, "
                            f"{int(dev.in_margin.sum())} in the trim margin)",
                            hint="check the scan: it should cover most of the plate")


def _check_size(uv_design: np.ndarray, measured_local: np.ndarray, margin_mm: float = 0.0) -> None:
    """Raise GeometryError when the scan's length is out of proportion with the design's.

    ``measured_local`` are the scan's points in its own frame. A scan that still carries
    its trim margin may be up to ``SIZE_RATIO[1]`` times the design's length plus twice the
    margin.
    """
    design_mm = float(np.ptp(uv_design[:, 0]))
    scan_mm = float(np.ptp(measured_local[:, 0]))
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
