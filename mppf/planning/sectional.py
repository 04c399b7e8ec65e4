"""Sectional planning: a plate larger than the bed, planned section by section.

:func:`plan_plate` plans a plate in one piece when it fits the bed (:func:`mppf.planning.plan.plan_job`)
and in sections otherwise (:func:`plan_sectional`). The split, the order, the marks and the blend
weights are :mod:`mppf.planning.sections`; the job's sections :mod:`mppf.model.job_sections`.
See ``docs/sections.md``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from mppf.core.polygon import convex_outline, offset_convex
from mppf.core.progress import NULL_REPORTER
from mppf.core.rigid import fit_rigid
from mppf.core.transform import apply_tf, make_tf
from mppf.geometry.surface import FittedPlate, fit_plate
from mppf.model.job import Job
from mppf.model.job_parts import PlateLayout, StepStrokes
from mppf.model.job_provenance import SectionalSummary, TransitionReport
from mppf.model.job_sections import Section
from mppf.model.plan_options import PlanOptions
from mppf.model.press import PressConfig
from mppf.planning.belongs import check_flat_belongs, design_area_mm2
from mppf.planning.contact import PlacedSurface, tip_heights
from mppf.planning.placement import FlatPlacement, fits_bed, lay_flat, register_design
from mppf.planning.plan import SURFACE_DEGREE, SURFACE_KIND, first_press_material, first_press_report, plan_job
from mppf.planning.plan_steps import (PlannedPiece, active_punches, as_validation, check_plan_inputs, check_trim,
                                      least_travel_pose, on_grid, planner_reports, section_reports,
                                      steps_within_limit)
from mppf.planning.section_start import formed_punches, plan_section_steps
from mppf.planning.sectional_borders import BORDER_STEP_LIMIT_MM, border_steps, border_warnings, recovered_residual
from mppf.planning.sectional_marks import SectionContext, section_marks
from mppf.planning.sectional_overbend import closer_fit, whole_target
from mppf.planning.sections import TRANSITION_PITCHES, earlier_weight, index_offset, shifted, split_plate
from mppf.planning.steps import steps_needed
from mppf.planning.validate import validate_steps
from mppf.registration.register import Registration

__all__ = ["BORDER_STEP_LIMIT_MM", "apply_section_corrections", "border_warnings", "from_formed_plate", "plan_plate",
           "plan_sectional", "recovered_residual"]


def plan_plate(design_points, flat_points, press: PressConfig, thickness_mm: float,
               options: PlanOptions = PlanOptions(), *, design_faces=None, inputs: dict | None = None,
               reporter=NULL_REPORTER, target_offset_mm=None) -> Job:
    """Plan a plate in one piece when its net flat fits the bed, in sections otherwise.

    Parameters are those of :func:`mppf.planning.plan.plan_job`; ``options.transition_mm`` is the least
    width two neighbouring sections share (:func:`split_plate`); ``target_offset_mm`` as
    :func:`plan_sectional` (only for a plate in sections).
    """
    design, flat, t, _ = check_plan_inputs(design_points, flat_points, press, thickness_mm, options.steps,
                                           options.material, options.springback, options.margin_mm)
    if fits_bed(lay_flat(flat, press, t), press):
        if target_offset_mm is not None:
            from mppf.core.errors import InputError

            raise InputError("a correction of the whole plate's target is for a plate planned in sections",
                             hint="this plate fits the bed: correct its strokes with the loop's correction")
        return plan_job(design, flat, press, t, options, design_faces=design_faces, inputs=inputs, reporter=reporter)
    return plan_sectional(design, flat, press, t, options, design_faces=design_faces, inputs=inputs,
                          reporter=reporter, target_offset_mm=target_offset_mm)


@dataclass(frozen=True)
class _WholePlate:
    """What the sections of one plate share: the flat laid, the design's fit and registration, the split."""

    placement: FlatPlacement  # the flat on an unlimited bed: the plate coordinates
    fitted: FittedPlate  # the design's own fit (the reports)
    registration: Registration
    belongs: dict
    split: object  # mppf.planning.sections.split_plate's split
    zone_mm: float  # the transition zone's width
    springback_report: dict


def plan_sectional(design_points, flat_points, press: PressConfig, thickness_mm: float,
                   options: PlanOptions = PlanOptions(), *, design_faces=None, inputs: dict | None = None,
                   reporter=NULL_REPORTER, target_offset_mm=None) -> Job:
    """Plan the strokes of a plate larger than the bed, section by section.

    Each section is the plate shifted on the bed (by whole punch pitches) with its own pose
    (offset and tilt of least travel); its strokes are the exact ball contact of the design so
    placed, or with ``options.springback`` of the whole plate's one over-bent target
    (:mod:`mppf.planning.sectional_overbend`), the same surface for every section. Parameters as
    :func:`mppf.planning.plan.plan_job`, and

    target_offset_mm : (n,) float, optional
        A correction of the whole plate: the over-bent target moved along its normal by this much (mm) at
        each design point (:meth:`mppf.planning.sectional_overbend.WholeTarget.corrected`); needs
        ``options.springback``.

    Returns
    -------
    Job
        With ``sections`` in pressing order; the job's own steps, transforms and layout are
        section 1's; ``sectional`` the split and the largest step between sections of the
        design recovered from the strokes.
    """
    design, flat, t, margin = check_plan_inputs(design_points, flat_points, press, thickness_mm, options.steps,
                                                options.material, options.springback, options.margin_mm)
    material, springback = options.material, options.springback
    planned_material = first_press_material(material, springback, options.yield_uncertainty_pct)
    # 1. lay the flat on an unlimited bed: the plate coordinates
    placement = lay_flat(flat, press, t)
    # 2. fit the design, register it onto the flat, check the flat is its unfolding
    fitted = fit_plate(design, degree=SURFACE_DEGREE, kind=SURFACE_KIND, faces=design_faces)
    reporter.info("registering the design onto the flat plate")
    registration = register_design(design, placement.flat_press_mm, reporter=reporter)
    belongs = check_flat_belongs(design, placement.flat_press_mm, registration.method == "paired",
                                 design_area_mm2(fitted, design, design_faces))
    # 3. split the plate into sections covering the bed, in pressing order
    split = split_plate(placement.size_mm, press, transition_mm=options.transition_mm)
    zone = TRANSITION_PITCHES * max(press.pitch_x_mm, press.pitch_y_mm) if options.transition_mm is None \
        else options.transition_mm
    reporter.info(f"the plate needs {split.n_sections} sections ({split.counts[0]} along x {split.counts[1]} across)")
    # 4. each section: contact in its pose, blended, steps, marks
    # one surface for every section: the sections then press the same shape where they meet; with springback
    # one over-bent target of that surface for the whole plate, the material's points moved onto it
    whole = _whole_surface(fitted, design, design_faces)
    target = whole_target(whole, design, press, t, planned_material, margin) if springback else None
    if target_offset_mm is not None:
        target = _corrected_target(target, design, target_offset_mm)
    springback_report = {**target.report, "first_press": first_press_report(material, options.yield_uncertainty_pct)} \
        if springback else {"enabled": False}
    ctx = SectionContext(press=press, fitted=whole, design=design, flat_file=flat, registration=registration,
                          thickness_mm=t, margin_mm=margin, material=material, target=target,
                          points=design if target is None else target.material_points(design))
    planned = []
    for k, (cell, centre) in enumerate(zip(split.cells, split.bed_centres_mm), start=1):
        reporter.info(f"planning section {k} of {split.n_sections}")
        planned.append(_plan_section(k, cell, centre, planned, zone, options.steps, placement, ctx))
    # 5. the design recovered from the strokes must not step where sections meet
    border = border_steps(press, planned, t)
    whole_plate = _WholePlate(placement, fitted, registration, belongs, split, float(zone), springback_report)
    return _assemble(planned, border, whole_plate, inputs, press, t)


def _corrected_target(target, design, offset_mm):
    """The target moved by the correction field ``offset_mm`` at the design points, checked."""
    from mppf.core.errors import InputError

    offset = np.asarray(offset_mm, dtype=float)
    if target is None:
        raise InputError("a correction of the whole plate's target needs the springback target",
                         hint="plan with springback on (the loop's default)")
    if offset.shape != (len(design),):
        raise InputError(f"the target's correction must be one finite value (mm) per design point "
                         f"({len(design)}); got shape {offset.shape}",
                         hint="give the correction at every design point, 0 where none")
    if not np.isfinite(offset).all():
        raise InputError(f"the target's correction must be one finite value (mm) per design point; "
                         f"{int(np.sum(~np.isfinite(offset)))} of {len(offset)} are not finite",
                         hint="give the correction at every design point, 0 where none")
    return target.corrected(design, offset)


def _plan_section(index, cell, centre, earlier, zone, steps, placement, ctx: SectionContext) -> dict:
    """One section: pose, contact strokes, the blend weights, the steps and the marks."""
    press, t, margin = ctx.press, ctx.thickness_mm, ctx.margin_mm
    tf_press_plate = make_tf(translation=[-centre[0], -centre[1], 0.0])
    # the plate's part on the bed (as pressed: on the over-bent target with springback) laid level onto its flat
    flat_press = apply_tf(tf_press_plate, placement.flat_press_mm)
    fitted, tf_reg, on_bed = _section_fit(press, ctx, flat_press, tf_press_plate @ ctx.registration.tf)
    target_plate, surface = ctx.target, fitted.surface
    shape_press = apply_tf(tf_reg, ctx.points)
    outline_xy = offset_convex(convex_outline(shape_press[:, :2], "the placed design"), margin)
    active = active_punches(press, outline_xy)
    # the section's pose of least travel; the exact ball contact of the surface so placed (the design's or the
    # whole plate's over-bent target: the same for every section, so no blend of corrections is needed)
    pose = least_travel_pose(press, PlacedSurface(surface, tf_reg @ fitted.frame.tf_world_local), active, t)
    tf_press_design = pose.tf_adjust @ tf_reg
    upper, lower = on_grid(press, active, pose.upper_mm), on_grid(press, active, pose.lower_mm)
    net = convex_outline(apply_tf(pose.tf_adjust, shape_press)[:, :2], "the placed design")
    outline = offset_convex(net, margin)
    # the design's own mid heights in the section's pose (the loop's target)
    design_up, design_lo = (upper, lower) if target_plate is None else _contact(press, ctx.fitted,
                                                                                tf_press_design, active, t)
    target = 0.5 * (design_up + design_lo)
    trim = check_trim(pose.contact_xy_mm, outline_xy, press)
    no_change = np.zeros(press.shape)
    weight, d_up, d_lo = _blend(press, centre, active, no_change, no_change, earlier, zone, placement.size_mm / 2.0)
    final_up, final_lo = np.where(active, upper + d_up, np.nan), np.where(active, lower + d_lo, np.nan)
    # press steps from flat, validated (from the formed plate: from_formed_plate)
    n_steps = steps if steps is not None else steps_needed(final_up, final_lo, active, press, t)
    step_list = steps_within_limit(final_up, final_lo, active, press, t, n_steps)
    validation = validate_steps(step_list, press, t)
    validation["contact_beyond_edge_mm"] = trim
    tf_press_flat = tf_press_plate @ placement.tf_press_flat
    placed = PlacedSurface(surface, tf_press_design @ fitted.frame.tf_world_local)
    marks = section_marks(press, active & active_punches(press, net), centre, tf_press_flat, placed, fitted, ctx, on_bed)
    travel = float(max(np.abs(final_up[active] - t).max(), np.abs(final_lo[active]).max()))
    reports = section_reports(pose, travel, validation, int(n_steps), active,
                              placement.corners_mm + [-centre[0], -centre[1], 0.0])
    transition = TransitionReport(zone_mm=float(zone), blended_punches=int((active & (weight < 1.0 - 1e-9)).sum()))
    section = Section(index=index, cell=tuple(cell), plate_centre_mm=-np.asarray(centre, dtype=float),
                      marks_plate_mm=marks[0], marks_flat_mm=marks[1], marks_press_mm=marks[2],
                      mark_punches=marks[3], steps=step_list, tf_press_design=tf_press_design,
                      tf_press_flat=tf_press_flat,
                      layout=PlateLayout(outline_mm=outline, net_outline_mm=net, margin_mm=margin,
                                         design_mid_mm=target, material=ctx.material),
                      own_weight=np.where(active, weight, np.nan), reports=reports, transition=transition)
    return {"section": section, "centre": np.asarray(centre, dtype=float), "active": active, "pose": pose,
            "delta": (d_up, d_lo), "contact": (upper, lower), "fitted": fitted}


def _whole_surface(fitted, design, design_faces):
    """The surface every section presses: the degree-4 polynomial, or the B-spline where the polynomial misses.

    The polynomial extends smoothly under the trim margin (where a B-spline, beyond its knots, does
    not); over 9 m of a stern plate it misses the design by up to 3 mm, the spline by 0.7 mm.
    """
    return closer_fit(fitted, lambda: fit_plate(design, kind="spline", faces=design_faces))


def _section_fit(press: PressConfig, ctx: SectionContext, flat_press, tf_whole):
    """The surface every section presses, its ``tf_press_design`` before the pose, and the points on the bed.

    Paired points (the unfolding's order): the plate's points whose flat points lie over the bed (with
    the margin and the trim allowance) are laid onto their flat points by the rigid fit, so the
    section lies level over its own part of the flat whatever the plate's curvature elsewhere. The
    points are the design's, or with springback where their material lies on the whole plate's
    over-bent target (:mod:`mppf.planning.sectional_overbend`). The surface is the whole plate's (the
    same in every section: where sections meet they press the same shape, :func:`_whole_surface`).
    Unpaired: the whole plate's registration, shifted.
    """
    points, target = ctx.points, ctx.target
    reach = ctx.margin_mm + press.trim_allowance_mm
    half = np.array(press.bed_size_mm) / 2.0 + reach
    paired = points.shape == flat_press.shape
    on_bed = np.all(np.abs((flat_press if paired else apply_tf(tf_whole, points))[:, :2]) <= half, axis=1)
    few = on_bed.sum() < MIN_SECTION_POINTS
    if few:
        on_bed = np.ones(len(points), dtype=bool)
    # the surface pressed: the whole plate's, or the whole plate's over-bent target over this section
    fitted = ctx.fitted if target is None else target.section_fit(ctx.design[on_bed], reach + press.pitch_x_mm)
    if not paired or few:
        return fitted, tf_whole, on_bed
    return fitted, fit_rigid(points[on_bed], flat_press[on_bed]), on_bed


MIN_SECTION_POINTS = 30
"""Fewest paired points over a section for its own rigid fit onto the flat."""


def _contact(press: PressConfig, fitted, tf_press_design, active, t: float):
    """(rows, cols) upper and lower tip heights of the design's exact ball contact (NaN parked)."""
    gx, gy = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    placed = PlacedSurface(fitted.surface, tf_press_design @ fitted.frame.tf_world_local)
    up, lo = tip_heights(placed, gx[active], gy[active], tip_radius_mm=press.tip_radius_mm, thickness_mm=t)
    return on_grid(press, active, up.tip_mm), on_grid(press, active, lo.tip_mm)


def _blend(press, centre, active, own_up, own_lo, earlier, zone, plate_half):
    """Weight of the own correction and the blended corrections: the formed plate's near its sections."""
    prev_w = np.zeros(press.shape)
    prev_up, prev_lo = np.zeros(press.shape), np.zeros(press.shape)
    for done in earlier:
        offset = index_offset(press, centre, done["centre"])
        covered = shifted(done["active"], offset, False) & active
        w = np.where(covered, earlier_weight(press, centre, done["centre"], zone, plate_half), 0.0)
        take = w > prev_w
        prev_w = np.where(take, w, prev_w)
        prev_up = np.where(take, shifted(done["delta"][0], offset, 0.0), prev_up)
        prev_lo = np.where(take, shifted(done["delta"][1], offset, 0.0), prev_lo)
    own = 1.0 - prev_w
    blended_up = np.where(active, own * own_up + prev_w * prev_up, 0.0)
    return own, blended_up, np.where(active, own * own_lo + prev_w * prev_lo, 0.0)


def _assemble(planned, border, plate: _WholePlate, inputs, press: PressConfig, t: float) -> Job:
    """The sectional job: section 1 as the job's own steps and layout, every section in ``sections``."""
    split, zone, placement, springback_report = plate.split, plate.zone_mm, plate.placement, plate.springback_report
    sections = []
    for p, step in zip(planned, border):
        section = p["section"]
        sections.append(dataclasses.replace(section, transition=dataclasses.replace(section.transition,
                                                                                    border_step_mm=float(step))))
    first = planned[0]
    s1 = sections[0]
    shift = np.array([*s1.plate_centre_mm, 0.0])
    placed1 = FlatPlacement(s1.tf_press_flat, placement.flat_press_mm + shift, placement.size_mm,
                            placement.corners_mm + shift)
    final = s1.steps[-1]
    reports = planner_reports(PlannedPiece(
        fitted=plate.fitted, registration=plate.registration, belongs=plate.belongs, placement=placed1, pose=first["pose"],
        upper_mm=final.upper_mm, lower_mm=final.lower_mm, active=first["active"], thickness_mm=t,
        validation=s1.reports.validation, n_steps=len(s1.steps), springback=springback_report, inputs=inputs))
    pose = dataclasses.replace(reports.pose, max_travel_mm=s1.reports.max_travel_mm)  # section 1's own travel
    reports = dataclasses.replace(reports, pose=pose)
    sectional = SectionalSummary(
        n_sections=split.n_sections, counts=tuple(split.counts), spacing_mm=tuple(split.spacing_mm.tolist()),
        shared_mm=tuple(split.transition_mm.tolist()), transition_zone_mm=float(zone),
        order="along x from -x to +x; across back and forth at each position along",
        plate_size_mm=np.asarray(placement.size_mm, dtype=float),
        n_steps_total=int(sum(len(s.steps) for s in sections)),
        max_travel_mm=float(max(s.reports.max_travel_mm for s in sections)),
        max_border_step_mm=float(max(border)),
        warnings=tuple(border_warnings(border, bool(springback_report["enabled"]))),
    )
    return Job(press=press, thickness_mm=t, steps=s1.steps, tf_press_design=s1.tf_press_design,
               tf_press_flat=s1.tf_press_flat, layout=s1.layout, reports=reports, sections=sections,
               sectional=sectional)


def apply_section_corrections(job: Job, corrections, *, steps: int | None = None, blend: bool = True) -> Job:
    """The job with each section's final strokes corrected, blended in the transition zones as planned.

    The loop's per-section correction (or any other): ``corrections[k]`` = (upper, lower) (rows, cols)
    mm to add to section k+1's final strokes. Section by section in pressing order, the correction
    pressed is ``(1 - w) own + w earlier`` as in planning (``own_weight``: ``1 - w``), so the formed
    plate keeps no step where sections meet; ``blend=False``: every section's own correction at all its
    punches (the corrections are one correction of the whole plate, the same where sections overlap up to
    each section's rigid pose). The strokes are held to the press's stroke limits; the steps
    go again from flat to the new strokes, validated.

    Raises
    ------
    InputError
        Not a sectional job, or not one correction pair of the press's shape per section;
        LimitError for corrected strokes the press cannot take.
    """
    from mppf.core.errors import InputError

    if job.sections is None or len(corrections) != len(job.sections):
        raise InputError(f"need one correction per section ({0 if job.sections is None else len(job.sections)}), "
                         f"got {len(corrections)}")
    press, t = job.press, job.thickness_mm
    info = job.sectional
    plate_half, zone = np.asarray(info.plate_size_mm) / 2.0, float(info.transition_zone_mm)
    done, sections = [], []
    for s, (c_up, c_lo) in zip(job.sections, corrections):
        c_up, c_lo = np.asarray(c_up, dtype=float), np.asarray(c_lo, dtype=float)
        if c_up.shape != press.shape or c_lo.shape != press.shape:
            raise InputError(f"section {s.index}: corrections must be {press.rows} x {press.cols} grids")
        final, centre = s.steps[-1], -np.asarray(s.plate_centre_mm, dtype=float)
        own_up, own_lo = np.nan_to_num(c_up), np.nan_to_num(c_lo)
        _, d_up, d_lo = _blend(press, centre, final.active, own_up, own_lo, done if blend else [], zone, plate_half)
        # held to the strokes the press has (a blend of two sections' corrections may reach past them)
        up = np.where(final.active, np.clip(final.upper_mm + d_up, press.upper.min_mm, press.upper.max_mm), np.nan)
        lo = np.where(final.active, np.clip(final.lower_mm + d_lo, press.lower.min_mm, press.lower.max_mm), np.nan)
        formed = formed_punches(press, centre, final.active, [(d["centre"], d["active"]) for d in done]) \
            if s.transition is not None and s.transition.start_share is not None else np.zeros(press.shape, bool)
        start, step_list, share = plan_section_steps(press, t, s.layout.design_mid_mm,
                                                     StepStrokes(up, lo, final.active), formed, steps)
        n = len(step_list)
        validation = validate_steps(step_list, press, t, start=start)
        done.append({"centre": centre, "active": final.active, "delta": (d_up, d_lo)})
        transition = None if s.transition is None else dataclasses.replace(s.transition, start_share=share)
        sections.append(dataclasses.replace(s, steps=step_list, transition=transition, reports=dataclasses.replace(
            s.reports, validation=as_validation(validation), n_steps=int(n))))
    return dataclasses.replace(job, steps=sections[0].steps, sections=sections,
                               reports=dataclasses.replace(job.reports, validation=sections[0].reports.validation))


def from_formed_plate(job):
    """The sectional job with every later section's steps from the plate the sections before it formed.

    Each section after the first that meets formed plate gets the start and steps of
    :func:`mppf.planning.section_start.plan_section_steps` (its ``transition.start_share`` set; the loop's
    corrections, :func:`apply_section_corrections`, keep starting there); the final strokes are
    unchanged, every section validated from its start. The planner itself presses every section from flat:
    measured on the steel-plate simulator this start did not make the first press better
    (``benchmarks/results/2026-12-06-sectional-first-press.md``).

    Raises
    ------
    InputError
        Not a sectional job.
    """
    from mppf.core.errors import InputError

    if job.sections is None:
        raise InputError("only a plate planned in sections has later sections to start from the formed plate",
                         hint="plan the plate with plan_plate; a plate that fits the bed is pressed in one piece")
    marked = [s if s.transition is None or k == 0 else
              dataclasses.replace(s, transition=dataclasses.replace(s.transition, start_share=1.0))
              for k, s in enumerate(job.sections)]
    zeros = [(np.zeros(job.press.shape), np.zeros(job.press.shape))] * len(marked)
    started = apply_section_corrections(dataclasses.replace(job, sections=marked), zeros, blend=False)
    total = int(sum(len(s.steps) for s in started.sections))
    sectional = None if job.sectional is None else dataclasses.replace(job.sectional, n_steps_total=total)
    return dataclasses.replace(started, sectional=sectional)
