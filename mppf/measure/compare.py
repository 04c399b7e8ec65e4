"""Compare a measured (scanned) plate with its design: register, deviate, summarise.

The steps of :func:`compare` (the math is in ``docs/compare.md``):

1. Fit the design surface: the design's own frame (best-fit plane) and a bicubic
   B-spline height field ``w = D(u, v)`` (:func:`mppf.geometry.surface.fit_plate`).
2. Offset the design to the measured skin: the design file is the mid-surface, a scanner
   sees a skin; ``CompareOptions.offset_mm`` moves the design along its normal (``+t/2`` for the top skin)
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
   design whose outline and shape say it is this plate, :mod:`mppf.measure.same_plate`:
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

from dataclasses import dataclass, replace

import numpy as np

from mppf.core.errors import InputError
from mppf.core.transform import apply_tf, as_points
from mppf.geometry.surface import fit_plate
from mppf.measure import checks
from mppf.measure.aside import left_out_notes, scan_index_of, set_aside_report
from mppf.measure.coverage import coverage
from mppf.measure.decision import Figures, Limits, verdict
from mppf.measure.deviations import DesignSkin, normal_sign
from mppf.measure.form import form_of
from mppf.measure.localfit import spatial_query
from mppf.measure.options import CompareOptions
from mppf.measure.outliers import clear_by_rescans, find_outliers_by_scan
from mppf.measure.punches import edge_at_punches, nearest_punch, punch_deviations
from mppf.measure.result import Comparison
from mppf.measure.statistics import statistics
from mppf.registration.outline_fit import OutlineDesign, refit_outline
from mppf.registration.register import register_icp
from mppf.registration.scan_start import choose_start, known_start
from mppf.registration.settings import RegisterOptions, ScanStages
from mppf.registration.target import build_target, prepare
from mppf.registration.trust import sample_index

MIN_POINTS = checks.MIN_POINTS
"""Fewest measured points a comparison accepts."""

STAGES = ScanStages()
"""The two ICP stages of the scan's registration (defaults of :class:`~mppf.registration.settings.ScanStages`)."""


DEFAULT = CompareOptions()
"""The default options (:class:`~mppf.measure.options.CompareOptions`)."""


def compare(design_points, measured_points, options: CompareOptions = DEFAULT) -> Comparison:
    """Register a scan onto its design and measure the deviation of every point.

    Parameters
    ----------
    design_points : (m, 3) float, mm
        The design plate (mid-surface), design coordinates.
    measured_points : (n, 3) float, mm
        The scan, in any pose.
    options : CompareOptions
        Tolerances, the skin, the press pose and punch grid, the start, the margin, the
        coverage gaps (:class:`mppf.measure.options.CompareOptions`, checked when built).

    Returns
    -------
    Comparison

    Raises
    ------
    InputError
        Bad shapes of the points, or a ``scan_index`` of another length than the scan.
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
    if not isinstance(options, CompareOptions):
        raise InputError(f"compare takes its options as a CompareOptions, got {type(options).__name__}",
                         hint="build them with mppf.measure.options.CompareOptions(...)")
    design = as_points(design_points, name="design points")
    measured = as_points(measured_points, name="measured points")
    checks.check_points(measured)
    # 1-3. the design skin (normal up in press coordinates when known), the target, the registered scan
    placed = _place(design, measured, options)
    # 5. set aside only certain scanner artefacts (the margin's points are neighbours too)
    parts = _set_aside(placed.dev, options, measured.shape[0])
    # 6. statistics, form, coverage and punch deviations; 7. the one decision rule
    return _judge(design, placed, parts, options)


@dataclass
class _Placed:
    """The registered scan: design fit, skin, registration, transform, deviations, plate evidence, notes."""

    fitted: object
    skin: DesignSkin
    reg: object
    transform: np.ndarray
    dev: object
    badly: object
    notes: list


@dataclass
class _Parts:
    """The set-aside artefacts and which points count: inliers (net), measured (net and margin), net."""

    artefacts: object
    clearing: object
    set_aside: np.ndarray
    inlier: np.ndarray
    measured_ok: np.ndarray
    net: np.ndarray


def _place(design: np.ndarray, measured: np.ndarray, options: CompareOptions) -> _Placed:
    """Steps 1-4: the design skin and target, the start, the two ICP stages, the outline fit, the match check."""
    tf_press = options.tf_press_design
    fitted = fit_plate(design, kind="spline", faces=options.design_faces, source="design")
    skin = DesignSkin(fitted, design, normal_sign(fitted.frame, tf_press), options.offset_mm, options.margin_mm)
    scan = prepare(measured, "the scan")  # checked and framed once for every ICP run below
    checks.check_size(skin.uv, scan.frame.to_local(scan.points), options.margin_mm)
    # the registration target: the skin sampled densely over the outline grown by the margin, built once
    target = build_target(skin.dense_points(), "the design skin")
    # the start (principal axes, converged; the reference mark or the hint settle the turn), then the ICP
    start = (choose_start(scan, target, options.rotation_hint, options.reference_mark, skin.length_mm)
             if options.start_from is None else known_start(options.start_from))
    reg, dev, reg_note = _register(scan, target, skin, start.tf)
    reg = replace(reg, ambiguous_start=start.ambiguous, init={**reg.init, **start.info()})
    notes = [f"{start.note}; {reg_note}"]
    # 4. on the press the outline places the plate in the plane, the deviations out of it
    transform = reg.tf
    if options.outline_fitted:
        outline = OutlineDesign(fitted.frame, skin.uv, skin.at(skin.uv), tf_press, options.margin_mm)
        transform, note = refit_outline(measured, transform, outline, skin.heights(measured))
        notes[0] = f"{notes[0]}; {note}"
        dev = skin.deviate(measured, transform)
    # another plate or other units: refused; this plate far from its design: judged (badly formed)
    badly = checks.check_match(dev, skin, options.tolerance_mm, reg, options.expected_points)
    if badly is not None:
        notes.append(f"badly formed: {badly.describe()}: this plate, far out of tolerance")
    # a scan of this plate that fits two ways round is not judged (exit 4, both candidates shown)
    start.require_settled()
    return _Placed(fitted, skin, reg, transform, dev, badly, notes)


def _set_aside(dev, options: CompareOptions, n_points: int) -> _Parts:
    """Step 5: the scanner artefacts (per scan of a union), cleared by rescans; which points count."""
    index = scan_index_of(options.scan_index, n_points)
    artefacts = find_outliers_by_scan(dev.uv, dev.deviation_mm, ~dev.outside, index)
    clearing = clear_by_rescans(dev.uv, dev.deviation_mm, artefacts.mask, ~dev.outside, index, options.tolerance_mm)
    set_aside = artefacts.mask
    inlier = ~dev.outside & ~set_aside & ~dev.in_margin
    checks.check_usable(inlier, set_aside, dev)
    return _Parts(artefacts, clearing, set_aside, inlier, ~dev.outside & ~set_aside, ~dev.outside & ~dev.in_margin)


def _judge(design: np.ndarray, placed: _Placed, parts: _Parts, options: CompareOptions) -> Comparison:
    """Steps 6-7: statistics, form, set-aside report, coverage, punch deviations, the verdict; the Comparison."""
    dev, skin, tol = placed.dev, placed.skin, options.tolerance_mm
    stats = statistics(dev.deviation_mm[parts.inlier], tol, options.bins)
    within_pct = float(100.0 * np.mean(np.abs(dev.deviation_mm[parts.net]) <= tol))
    form, field = form_of(dev.uv, dev.deviation_mm, parts.inlier, parts.measured_ok, dev.in_margin)
    aside = set_aside_report(parts.set_aside & parts.net, dev, parts.artefacts, options, parts.clearing)
    notes = placed.notes + [field.describe(), aside.describe(tol),
                            *left_out_notes(parts.set_aside, dev, options.margin_mm)]
    # what of the net plate was not measured (occlusions, rim bands): gaps wider than allowed
    covered = coverage(skin.outline, _nearest(parts.artefacts, dev), parts.artefacts.spacing_mm, options.gap_mm,
                       options.max_gap_mm, _on_press(skin, options))
    notes.append(covered.describe())
    punch = _punches(design, placed, parts, options, notes)
    # the one decision rule: form max, RMS, set-aside points beyond the tolerance, coverage, badly formed
    form_max = float(abs(field.peak_mm))
    badly = placed.badly
    decided = verdict(Figures(form_max, stats.rms_mm, aside.count, aside.beyond_tolerance, aside.max_abs_mm,
                              covered.names(), len(covered.regions), covered.allowed_gap_mm,
                              "" if badly is None else badly.describe(), aside.cleared,
                              aside.cleared_text() if aside.cleared else "", aside.confirmed),
                      Limits(tol, options.rms_tolerance_mm))
    return Comparison(
        rms_mm=stats.rms_mm, max_abs_mm=stats.max_abs_mm, mean_mm=stats.mean_mm, std_mm=stats.std_mm,
        within_tolerance_pct=within_pct, tolerance_mm=tol, offset_mm=options.offset_mm,
        histogram_edges_mm=stats.histogram_edges_mm, histogram_counts=stats.histogram_counts,
        transform=placed.transform, registration=placed.reg, deviation_mm=dev.deviation_mm, inlier=parts.inlier,
        is_outlier=parts.set_aside, is_outside=dev.outside, measured_in_design=dev.moved, measured_uv_mm=dev.uv,
        design_frame=placed.fitted.frame, normal_sign=skin.sign, design_uv_mm=skin.uv,
        design_fit_rms_mm=float(placed.fitted.rms_mm), form_rms_mm=float(np.sqrt(np.mean(form[parts.inlier] ** 2))),
        form_max_abs_mm=form_max, form_deviation_mm=form, punch_deviation_mm=punch[0],
        punch_normal_deviation_mm=punch[1], punch_interpolated=punch[2], punch_edge_mm=punch[3], notes=notes,
        margin_mm=options.margin_mm, in_margin=dev.in_margin, rms_tolerance_mm=options.rms_tolerance_mm,
        verdict=decided, set_aside=aside, form=field.to_dict(), punch_label_base=options.punch_label_base,
        coverage=covered, plate_evidence=badly, is_cleared=parts.clearing.cleared & parts.set_aside,
    )


def _punches(design: np.ndarray, placed: _Placed, parts: _Parts, options: CompareOptions, notes: list) -> tuple:
    """The deviation at each punch: (along z, along the normal, interpolated, at the edge), or four None."""
    if options.punch_xy_mm is None:
        return None, None, None, None
    grid, tf, skin, dev = options.punch_xy_mm, options.tf_press_design, placed.skin, placed.dev
    punch, punch_n, punch_interp = punch_deviations(grid, tf, skin, dev, parts.measured_ok, design,
                                                    options.punch_radius_mm)
    punch_edge = edge_at_punches(grid, tf, skin, dev, parts.measured_ok & parts.net, np.isfinite(punch))
    notes.append(f"punch deviations: {int(np.isfinite(punch).sum())} punches on the plate, "
                 f"{int(punch_interp.sum())} interpolated across gaps in the scan")
    return punch, punch_n, punch_interp, punch_edge


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
    point = register_icp(scan, target, RegisterOptions(
        method="point", init=init, pin_outline=False, max_points=stages.point_points,
        max_iterations=stages.point_iterations, check_starts=False))
    plane = register_icp(scan, target, RegisterOptions(
        method="plane", init=point.tf, trim_fraction=stages.trim_fraction, robust=stages.robust, pin_outline="auto",
        max_points=stages.plane_points, max_iterations=stages.plane_iterations, check_starts=False))
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


def _on_press(skin: DesignSkin, options: CompareOptions):
    """``where(uv) -> (press xy, nearest punch)`` of a place on the design plane, or None without the press pose."""
    if options.tf_press_design is None:
        return None
    tf, punch_xy_mm, label_base = options.tf_press_design, options.punch_xy_mm, options.punch_label_base

    def where(uv):
        press_xy = apply_tf(tf, skin.at(np.asarray(uv, dtype=float)[None]))[0, :2]
        punch = None if punch_xy_mm is None else nearest_punch(np.asarray(punch_xy_mm, dtype=float), press_xy,
                                                               label_base)
        return press_xy, punch

    return where

