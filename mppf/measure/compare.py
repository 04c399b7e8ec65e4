"""Compare a measured (scanned) plate with its design: register, deviate, summarise.

The steps of :func:`compare` (the math is in ``docs/compare.md``):

1. Fit the design surface: the design's own frame (best-fit plane) and a bicubic
   B-spline height field ``w = D(u, v)`` (:func:`mppf.geometry.surface.fit_plate`).
2. Offset the design to the measured skin: the design file is the mid-surface, a scanner
   sees a skin; ``offset_mm`` moves the design along its normal (``+t/2`` for the top skin)
   (:class:`mppf.measure.deviations.DesignSkin`). The skin, sampled densely, is the
   registration target, built once (:func:`mppf.registration.target.build_target`).
3. Register the scan onto it: the start from the principal axes, converged and settled by
   a reference mark or a rotation hint (:mod:`mppf.registration.scan_start`; a tie nothing
   settles is not judged: :class:`~mppf.registration.scan_start.AmbiguousStart`); then
   point-to-point ICP (keeps the scan centred on the plate), then point-to-plane ICP with
   trimmed, Huber-weighted pairs (accurate along the normal, ignores outliers), the outline
   pinning the in-plane pose only along the directions the surface leaves free, as
   ``mppf register`` does (:mod:`mppf.registration.pin`); the point
   result is kept if the plane stage slid part of the scan off the design's edge
   (:func:`mppf.registration.register.register_icp`). With punch positions (the loop) the
   outline then fixes the in-plane pose and the deviations' best plane the out-of-plane
   pose (:func:`mppf.registration.outline_fit.refit_outline`).
4. Signed normal deviation of EVERY measured point: its foot point on the design surface
   (:func:`mppf.geometry.localize.foot_points`), distance along the design normal minus the offset.
   Positive = the measured plate lies on the +normal side of the design ("above").
5. Set aside only what is certainly a scanner artefact: a point of a dense scan that its
   agreeing neighbours contradict (:mod:`mppf.measure.outliers`); on sparse data nothing.
   Every set-aside point is reported (``Comparison.set_aside``); points whose foot point
   falls outside the design are left out too.
   Smooth shape errors (a dent, springback) are never set aside: their neighbours agree.
   With ``scan_index`` (a union of scans in one frame) each scan is tested on its own points
   (:func:`mppf.measure.outliers.find_outliers_by_scan`), and a set-aside point beyond the tolerance
   that another scan re-measured within it is cleared, one another scan confirms never is
   (:func:`mppf.measure.outliers.clear_by_rescans`).
6. Statistics of the inliers (RMS, largest absolute, mean, histogram:
   :mod:`mppf.measure.statistics`; the share within the tolerance of every measured net
   point, set-aside ones included), the form deviation with its smoothing scale from the
   point spacing and the noise (:mod:`mppf.measure.form`) and, given the punch positions,
   the deviation at each punch (:mod:`mppf.measure.punches`).
   Coverage: the areas of the net plate not measured, gaps wider than the allowed gap
   (:mod:`mppf.measure.coverage`).
7. The verdict: the one decision rule (:func:`mppf.measure.decision.verdict`): form max,
   RMS, the set-aside points, the coverage, and a badly formed plate (a scan far from its
   design whose outline and shape say it is this plate, :mod:`mppf.measure.identity`:
   judged out of tolerance, not refused as another plate).

A trim margin (``margin_mm``: the excess band the scanned plate still carries around the
net outline) grows the registration target, the size check and the outline fit by the
margin; points in the band are measured (against the design surface's extension past its
edge) and used for the punch deviations, but left out of the statistics.

Which way is "+normal": with ``tf_press_design`` the design normal pointing up in press
coordinates (+z); without it the normal of the design's frame (:mod:`mppf.geometry.frame`: the
side from which a curved plate looks concave, like a bowl on the press bed).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from mppf.core.defaults import RMS_TOLERANCE_MM
from mppf.core.transform import apply_tf, as_points
from mppf.geometry.surface import fit_plate
from mppf.measure import checks
from mppf.measure.coverage import GAP_MM, MAX_GAP_MM, check_gaps, coverage
from mppf.measure.decision import Figures, Limits, verdict
from mppf.measure.deviations import DesignSkin, normal_sign
from mppf.measure.aside import left_out_notes, scan_index_of, set_aside_report
from mppf.measure.form import form_of
from mppf.measure.localfit import spatial_query
from mppf.measure.outliers import clear_by_rescans, find_outliers_by_scan
from mppf.measure.punches import edge_at_punches, nearest_punch, punch_deviations
from mppf.measure.result import Comparison
from mppf.measure.statistics import statistics
from mppf.registration.outline_fit import refit_outline
from mppf.registration.register import register_icp
from mppf.registration.scan_start import choose_start, known_start
from mppf.registration.settings import ScanStages
from mppf.registration.target import build_target, prepare
from mppf.registration.verdict import sample_index

MIN_POINTS = checks.MIN_POINTS
"""Fewest measured points a comparison accepts."""

STAGES = ScanStages()
"""The two ICP stages of the scan's registration (defaults of :class:`~mppf.registration.settings.ScanStages`)."""


def compare(
    design_points,
    measured_points,
    *,
    tolerance_mm: float = 2.5,
    rms_tolerance_mm: float = RMS_TOLERANCE_MM,
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
    punch_label_base: int = 1,
    gap_mm: float = GAP_MM,
    max_gap_mm: float = MAX_GAP_MM,
    expected_points: int | None = None,
    scan_index=None,
    start_from=None,
) -> Comparison:
    """Register a scan onto its design and measure the deviation of every point.

    Parameters
    ----------
    design_points : (m, 3) float, mm
        The design plate (mid-surface), design coordinates.
    measured_points : (n, 3) float, mm
        The scan, in any pose.
    tolerance_mm : float
        Allowed absolute form deviation.
    rms_tolerance_mm : float
        Allowed RMS of the measured points' deviations (the decision rule:
        :func:`mppf.measure.decision.verdict`).
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
    punch_label_base : int
        How punches are named in notes: row and column counted from this (the press file's
        ``label_base``, 1 by default).
    rotation_hint : (3, 3) or (4, 4) float, optional
        Rough rotation from measured into design coordinates (within about 45 deg), e.g.
        ``invert_tf(tf_press_design)`` when the scanner's axes are the press's. It picks
        which of the four principal-axes starts to use, so that a nearly symmetric plate
        is not registered turned by a half turn. Used only to break a tie: when the
        best two different poses of the four starts, each converged by a robust ICP, fit
        equally well within the noise (:func:`mppf.registration.scan_start.start_tie`).
        Default: the best fitting start; a tie with neither a mark nor a hint is not judged.
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
    gap_mm, max_gap_mm : float
        The smallest and the largest allowed gap in the measurement (mm across): "in
        tolerance" needs the whole net plate measured within ``max(gap_mm, 5 point
        spacings)``, at most ``max_gap_mm`` (:mod:`mppf.measure.coverage`); else "needs review"
        with the uncovered areas named.
    expected_points : int, optional
        How many points a scan of this plate has (the loop: the previous cycle's); one piece
        of the evidence that a scan far from its design is this plate, badly formed
        (:mod:`mppf.measure.identity`).
    scan_index : (n,) int, optional
        For a union of scans of the plate in one frame (the loop's rescans): the scan each measured
        point came from (0 the first scan, K its K-th rescan). A set-aside point beyond the tolerance
        that another scan measured within it is cleared (reported, not deciding); one another scan
        confirms never is (:func:`mppf.measure.outliers.clear_by_rescans`). Default: one scan.
    start_from : Comparison or (4, 4) float, optional
        A start already known: the comparison of a scan in the same frame (the loop's union of rescans
        starts from the first scan's), or its transform measured -> design. The choice of a start is
        skipped (the turn is the one that comparison settled, and its notes say how) and the
        registration refines it. Default: chosen (:func:`mppf.registration.scan_start.choose_start`).

    Returns
    -------
    Comparison

    Raises
    ------
    InputError
        Bad options or shapes.
    GeometryError
        Too few points, a design that is not a plate, or a scan that does not match the
        design (another plate or other units: its size, or most points far from it and its
        outline, shape or point count unlike the design's). A scan far from its design
        whose outline and shape are the design's is this plate badly formed: it is judged.
    AmbiguousStart
        The scan fits its design equally well two ways round (a nearly symmetric plate) and
        neither a reference mark nor a rotation hint says which (exit 4; both candidates in
        the message and in ``candidates``).
    """
    # 0. inputs
    design = as_points(design_points, name="design points")
    measured = as_points(measured_points, name="measured points")
    margin_mm = checks.check_options(tolerance_mm, offset_mm, measured, punch_xy_mm, tf_press_design, margin_mm)
    limits = Limits(float(tolerance_mm), float(rms_tolerance_mm))
    gap_mm, max_gap_mm = check_gaps(gap_mm, max_gap_mm)

    # 1. the design surface, its normal oriented (up in press coordinates when known)
    fitted = fit_plate(design, kind="spline", faces=design_faces, source="design")
    skin = DesignSkin(fitted, design, normal_sign(fitted.frame, tf_press_design), offset_mm, margin_mm)
    scan = prepare(measured, "the scan")  # checked and framed once for every ICP run below
    checks.check_size(skin.uv, scan.frame.to_local(scan.points), margin_mm)

    # 2. the registration target: the skin sampled densely over the outline grown by the margin,
    #    with its k-d tree, frame and normals built once for every ICP run below
    target = build_target(skin.dense_points(), "the design skin")

    # 3. the start (principal axes, converged; the reference mark or the hint settle the turn),
    #    point-to-point then point-to-plane ICP (pinned where free), the signed deviation of every point
    start = (choose_start(scan, target, rotation_hint, reference_mark, skin.length_mm) if start_from is None
             else known_start(start_from))
    reg, dev, reg_note = _register(scan, target, skin, start.tf)
    reg = replace(reg, ambiguous_start=start.ambiguous, init={**reg.init, **start.info()})
    notes = [f"{start.note}; {reg_note}"]

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
    # another plate or other units: refused; this plate far from its design: judged (badly formed)
    badly = checks.check_match(dev, skin, tolerance_mm, reg, expected_points)
    if badly is not None:
        notes.append(f"badly formed: {badly.describe()}: this plate, far out of tolerance")
    # a scan of this plate that fits two ways round is not judged (exit 4, both candidates shown)
    start.require_settled()

    # 5. set aside only certain scanner artefacts (the margin's points are neighbours too)
    index = scan_index_of(scan_index, measured.shape[0])
    artefacts = find_outliers_by_scan(dev.uv, dev.deviation_mm, ~dev.outside, index)
    clearing = clear_by_rescans(dev.uv, dev.deviation_mm, artefacts.mask, ~dev.outside, index, tolerance_mm)
    set_aside = artefacts.mask
    inlier = ~dev.outside & ~set_aside & ~dev.in_margin
    measured_ok = ~dev.outside & ~set_aside  # net and margin: the punch deviations
    checks.check_usable(inlier, set_aside, dev)

    # 6. statistics (the share within the tolerance of all measured net points), form and punch deviations
    stats = statistics(dev.deviation_mm[inlier], tolerance_mm, bins)
    net = ~dev.outside & ~dev.in_margin
    within_pct = float(100.0 * np.mean(np.abs(dev.deviation_mm[net]) <= tolerance_mm))
    form, field = form_of(dev.uv, dev.deviation_mm, inlier, measured_ok, dev.in_margin)
    aside = set_aside_report(set_aside & net, dev, artefacts, tolerance_mm, tf_press_design, punch_xy_mm, punch_label_base,
                       clearing, net)
    notes += [field.describe(), aside.describe(tolerance_mm), *left_out_notes(set_aside, dev, margin_mm)]
    # what of the net plate was not measured (occlusions, rim bands): gaps wider than allowed
    covered = coverage(skin.outline, _nearest(artefacts, dev), artefacts.spacing_mm, gap_mm, max_gap_mm,
                       _on_press(skin, tf_press_design, punch_xy_mm, punch_label_base))
    notes.append(covered.describe())
    punch = punch_n = punch_interp = punch_edge = None
    if punch_xy_mm is not None:
        punch, punch_n, punch_interp = punch_deviations(punch_xy_mm, tf_press_design, skin, dev, measured_ok, design,
                                                        punch_radius_mm)
        punch_edge = edge_at_punches(punch_xy_mm, tf_press_design, skin, dev, measured_ok & net, np.isfinite(punch))
        notes.append(f"punch deviations: {int(np.isfinite(punch).sum())} punches on the plate, "
                     f"{int(punch_interp.sum())} interpolated across gaps in the scan")

    # 7. the one decision rule: form max, RMS, set-aside points beyond the tolerance, coverage, badly formed
    form_max = float(abs(field.peak_mm))
    decided = verdict(Figures(form_max, stats.rms_mm, aside.count, aside.beyond_tolerance, aside.max_abs_mm,
                              covered.names(), len(covered.regions), covered.allowed_gap_mm,
                              "" if badly is None else badly.describe(), aside.cleared,
                              aside.cleared_text() if aside.cleared else "", aside.confirmed), limits)
    return Comparison(
        rms_mm=stats.rms_mm, max_abs_mm=stats.max_abs_mm, mean_mm=stats.mean_mm, std_mm=stats.std_mm,
        within_tolerance_pct=within_pct, tolerance_mm=float(tolerance_mm),
        offset_mm=float(offset_mm), histogram_edges_mm=stats.histogram_edges_mm,
        histogram_counts=stats.histogram_counts, transform=transform, registration=reg,
        deviation_mm=dev.deviation_mm, inlier=inlier, is_outlier=set_aside, is_outside=dev.outside,
        measured_in_design=dev.moved, measured_uv_mm=dev.uv, design_frame=fitted.frame, normal_sign=skin.sign,
        design_uv_mm=skin.uv, design_fit_rms_mm=float(fitted.rms_mm),
        form_rms_mm=float(np.sqrt(np.mean(form[inlier] ** 2))), form_max_abs_mm=form_max,
        form_deviation_mm=form, punch_deviation_mm=punch, punch_normal_deviation_mm=punch_n,
        punch_interpolated=punch_interp, punch_edge_mm=punch_edge, notes=notes, margin_mm=margin_mm, in_margin=dev.in_margin,
        rms_tolerance_mm=float(rms_tolerance_mm), verdict=decided, set_aside=aside, form=field.to_dict(),
        punch_label_base=int(punch_label_base), coverage=covered, identity=badly,
        is_cleared=clearing.cleared & set_aside,
    )


def _register(scan, target, skin: DesignSkin, init, stages: ScanStages = STAGES):
    """Register in two stages, then deviate every point: (Registration, Deviation, note).

    1. Point-to-point ICP (plain least squares) on the dense design skin: it keeps the
       scan centred on the plate even where the surface alone cannot fix the in-plane
       position (a cylinder's axis, a nearly flat plate).
    2. Point-to-plane ICP from there, trimmed and Huber-weighted: accurate along the
       normal, insensitive to outliers; the outline has its say in the in-plane pose only
       along the directions the surface leaves free (as ``register_icp`` pins). It is kept
       unless it slid part of the scan off the design's edge (grossly different shapes),
       then stage 1 is used.
    """
    point = register_icp(scan, target, method="point", init=init, pin_outline=False,
                         max_points=stages.point_points, max_iterations=stages.point_iterations, check_starts=False)
    plane = register_icp(scan, target, method="plane", init=point.tf, trim_fraction=stages.trim_fraction,
                         robust=stages.robust, pin_outline="auto", max_points=stages.plane_points,
                         max_iterations=stages.plane_iterations, check_starts=False)
    # the overhang of each on a seeded sample of the scan; the deviations of every point once, at the one kept
    sample = scan.points[sample_index(scan.n_points, stages.plane_points, seed=5)]
    point_out = skin.deviate(sample, point.tf).outside.mean()
    plane_out = skin.deviate(sample, plane.tf).outside.mean()
    if plane_out <= point_out + stages.overhang_fraction:
        return (plane, skin.deviate(scan.points, plane.tf),
                "registration: point-to-point, then point-to-plane (trimmed, Huber, pinned where free)")
    return point, skin.deviate(scan.points, point.tf), (
        f"registration: point-to-point only; point-to-plane left {100 * plane_out:.0f} % of the scan outside the "
        "design (the shapes differ much)")






def _nearest(artefacts, dev):
    """``nearest(cells) -> distances`` to the nearest measured point (not outside): the artefact test's k-d tree
    (set-aside points count as measured positions: one is set aside only where a dense scan surrounds it)."""
    tree = artefacts.tree
    if tree is None:
        from scipy.spatial import cKDTree

        tree = cKDTree(dev.uv[~dev.outside])
    return lambda cells: spatial_query(tree, cells, 1)[0][:, 0]


def _on_press(skin: DesignSkin, tf_press_design, punch_xy_mm, label_base: int):
    """``where(uv) -> (press xy, nearest punch)`` of a place on the design plane, or None without the press pose."""
    if tf_press_design is None:
        return None
    tf = np.asarray(tf_press_design, dtype=float)

    def where(uv):
        press_xy = apply_tf(tf, skin.at(np.asarray(uv, dtype=float)[None]))[0, :2]
        punch = None if punch_xy_mm is None else nearest_punch(np.asarray(punch_xy_mm, dtype=float), press_xy,
                                                               label_base)
        return press_xy, punch

    return where

