"""Stroke planning: a design surface and its flat plate -> strokes of both punch matrices.

:func:`plan_job` is the whole planner as a short sequence of calls, its options one frozen
:class:`mppf.model.plan_options.PlanOptions`; each stage is a
small module: :mod:`mppf.planning.placement` (flat on the bed, registration),
:mod:`mppf.planning.belongs` (the flat is the design's), :mod:`mppf.planning.pose` (offset and
tilt of least travel), :mod:`mppf.planning.contact` (exact ball-tip contact),
:mod:`mppf.planning.overbend` (springback pre-compensation),
:mod:`mppf.forming.precompensate` (its refinement on the plate model),
:mod:`mppf.planning.steps` (multi-step forming), :mod:`mppf.planning.validate` (the one job validator). The math is in
``docs/planning.md``; the job file in ``docs/file-formats.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.errors import GeometryError
from mppf.core.polygon import convex_outline, offset_convex
from mppf.core.progress import NULL_REPORTER
from mppf.core.transform import apply_tf
from mppf.correct.virtual_cycles import refine_strokes
from mppf.forming.material import check_yield_uncertainty, weakest_material
from mppf.geometry.surface import FittedPlate, fit_plate
from mppf.model.job import Job
from mppf.model.job_parts import PlateLayout, StepStrokes
from mppf.model.job_reports import RegistrationReport
from mppf.model.material import Material
from mppf.model.plan_options import PlanOptions
from mppf.model.press import PressConfig
from mppf.planning.belongs import check_flat_belongs, design_area_mm2
from mppf.planning.contact import PlacedSurface, tip_heights
from mppf.planning.overbend import overbend
from mppf.planning.placement import FlatPlacement, place_flat, register_design
from mppf.planning.plan_steps import (
    PlannedPiece,
    active_punches,
    check_plan_inputs,
    check_trim,
    least_travel_pose,
    on_grid,
    overbend_report,
    planner_reports,
    steps_within_limit,
)
from mppf.planning.steps import steps_needed
from mppf.planning.validate import validate_steps
from mppf.registration.register import Registration

SURFACE_KIND = "poly"
SURFACE_DEGREE = 4


def plan_job(design_points, flat_points, press: PressConfig, thickness_mm: float, options: PlanOptions = PlanOptions(),
             *, design_faces=None, inputs: dict | None = None, reporter=NULL_REPORTER) -> Job:
    """Plan the strokes of every punch of both matrices for one plate (in one piece on the bed).

    Parameters
    ----------
    design_points : (n, 3) float, mm
        The design (curved) plate's mid-surface, any coordinates (e.g. hull).
    flat_points : (k, 3) float, mm
        Its unfolded (flat) plate; with k == n paired with the design's points in order (as from unfold).
    press : PressConfig
    thickness_mm : float
        Plate thickness t, mm, > 0.
    options : PlanOptions
        Steps, material, springback, yield uncertainty and trim margin (``transition_mm`` is not used).
    design_faces : (m, 3) int, optional
        Mesh triangles of the design (better fold and area checks).
    inputs : dict, optional
        ``{"design": {"path", "sha256"}, "flat": {...}}`` recorded in the job.
    reporter : Reporter

    Returns
    -------
    Job
        Validated; ``layout``: the plate as cut, net outline, margin, design heights at the punches, material.

    Raises
    ------
    InputError, GeometryError, LimitError
        Bad inputs or options; a flat that is not the design's; a plate or strokes beyond the press.
    """
    design, flat, t, margin = check_plan_inputs(design_points, flat_points, press, thickness_mm, options.steps,
                                                options.material, options.springback, options.margin_mm)
    planned_material = first_press_material(options.material, options.springback, options.yield_uncertainty_pct)
    # 1. lay the flat on the bed, fit the design and register it onto the flat (which must be its unfolding)
    laid = _lay_and_register(design, flat, press, t, design_faces, reporter)
    # 2. the surface to press: the design, over-bent for springback (of the weakest plate declared) if asked
    surface, springback_report = _surface_to_press(laid.fitted, design, press, t, planned_material,
                                                   options.springback, margin)
    # 3. strokes: exact ball contact at the punches under the plate as cut, in the pose of least travel
    strokes = _contact_strokes(press, laid, surface, design, t, margin, reporter)
    # 4. the design's mid-surface height at each active punch (the refinement's and the loop's target)
    target = _design_heights(press, laid.fitted, strokes.tf_press_design, strokes.active, t)
    # 5. springback: virtual press cycles on the plate model (the planned material) against the design
    upper, lower = strokes.upper_mm, strokes.lower_mm
    if options.springback:
        reporter.info("refining the springback pre-compensation on the plate model")
        upper, lower, springback_report["refinement"] = _refine(press, upper, lower, strokes.active, target,
                                                                strokes.outline_mm, t, planned_material)
        springback_report["first_press"] = first_press_report(options.material, options.yield_uncertainty_pct)
    # 6. press steps from flat to the target, within the dimpling limit; validated before a job exists
    n_steps = options.steps if options.steps is not None else steps_needed(upper, lower, strokes.active, press, t)
    step_list = steps_within_limit(upper, lower, strokes.active, press, t, n_steps)
    validation = _validation(step_list, press, t, strokes)
    reports = planner_reports(PlannedPiece(laid.fitted, laid.registration, laid.belongs, laid.placement, strokes.pose,
                              upper, lower, strokes.active, t, validation, n_steps, springback_report, inputs))
    layout = PlateLayout(outline_mm=strokes.outline_mm, net_outline_mm=strokes.net_outline_mm, margin_mm=margin,
                         design_mid_mm=target, material=options.material)
    return Job(press=press, thickness_mm=t, steps=step_list, tf_press_design=strokes.tf_press_design,
               tf_press_flat=laid.placement.tf_press_flat, layout=layout, reports=reports)


@dataclass(frozen=True)
class _Laid:
    """The flat on the bed and the design registered onto it (:func:`_lay_and_register`)."""

    placement: FlatPlacement
    fitted: FittedPlate
    registration: Registration
    belongs: dict


@dataclass(frozen=True)
class _Strokes:
    """The contact strokes in the pose of least travel (:func:`_contact_strokes`); heights and outlines in mm."""

    active: np.ndarray  # (rows, cols) bool
    pose: object  # the pose report of least_travel_pose
    upper_mm: np.ndarray  # (rows, cols), NaN where inactive
    lower_mm: np.ndarray
    tf_press_design: np.ndarray  # (4, 4)
    outline_xy_mm: np.ndarray  # (p, 2): the plate as cut around the registered design, before the pose
    net_outline_mm: np.ndarray  # (q, 2): the net outline in the pose
    outline_mm: np.ndarray  # (r, 2): the net outline grown by the margin


def _lay_and_register(design, flat, press: PressConfig, t: float, design_faces, reporter) -> _Laid:
    """Lay the flat plate on the bed (centred, long side along x, bottom skin at z = 0), fit the design in its
    own frame, register it onto the flat and check that the flat is its unfolding."""
    reporter.info("placing the flat plate on the bed")
    placement = place_flat(flat, press, t)
    fitted = fit_plate(design, degree=SURFACE_DEGREE, kind=SURFACE_KIND, faces=design_faces)
    reporter.info("registering the design onto the flat plate")
    registration = register_design(design, placement.flat_press_mm, reporter=reporter)
    if registration.ambiguous_start:
        reporter.info("the plate is nearly symmetric: check that the plate lies the right way round "
                      "(registration start was ambiguous)")
    belongs = check_flat_belongs(design, placement.flat_press_mm, registration.method == "paired",
                                 design_area_mm2(fitted, design, design_faces))
    return _Laid(placement, fitted, registration, belongs)


def _contact_strokes(press: PressConfig, laid: _Laid, surface, design, t: float, margin: float,
                     reporter) -> _Strokes:
    """The active punches (axes inside the plate as cut: the design's outline seen from above, grown by the
    margin) and their exact ball-contact strokes with the offset and tilt of least travel."""
    design_press = apply_tf(laid.registration.tf, design)
    outline_xy = offset_convex(convex_outline(design_press[:, :2], "the placed design"), margin)
    active = active_punches(press, outline_xy)
    reporter.info(f"solving the contact of {2 * int(active.sum())} punches")
    placed = PlacedSurface(surface, laid.registration.tf @ laid.fitted.frame.tf_world_local)
    pose = least_travel_pose(press, placed, active, t)
    net_outline = convex_outline(apply_tf(pose.tf_adjust, design_press)[:, :2], "the placed design")
    return _Strokes(active=active, pose=pose, upper_mm=on_grid(press, active, pose.upper_mm),
                    lower_mm=on_grid(press, active, pose.lower_mm),
                    tf_press_design=pose.tf_adjust @ laid.registration.tf, outline_xy_mm=outline_xy,
                    net_outline_mm=net_outline, outline_mm=offset_convex(net_outline, margin))


def _validation(step_list, press: PressConfig, t: float, strokes: _Strokes) -> dict:
    """The job validation of the steps (:func:`mppf.planning.validate.validate_steps`) with the contact's figures."""
    validation = validate_steps(step_list, press, t)
    validation["contact_exact_fraction"] = float(np.mean(strokes.pose.exact))
    validation["contact_beyond_edge_mm"] = check_trim(strokes.pose.contact_xy_mm, strokes.outline_xy_mm, press)
    return validation


def first_press_material(material: Material | None, springback: bool, yield_uncertainty_pct: float):
    """The material the first press's springback is compensated for: the weakest plate of the declared range.

    Parameters
    ----------
    material : Material or None
        The nominal material.
    springback : bool
        Whether springback is compensated at all (without it: ``material`` unchanged).
    yield_uncertainty_pct : float
        Declared scatter of the yield stress, +- %, in [0, 50).

    Returns
    -------
    Material or None
        ``material`` with the yield stress x (1 - pct / 100)
        (:func:`mppf.forming.material.weakest_material`).

    Raises
    ------
    InputError
        A negative, NaN or too large uncertainty (checked whether or not springback is on).
    """
    pct = check_yield_uncertainty(yield_uncertainty_pct)
    if not springback or material is None:
        return material
    return weakest_material(material, pct)


def first_press_report(material: Material, yield_uncertainty_pct: float) -> dict:
    """What the first press assumed (the springback report's ``first_press``): the declared scatter, the
    nominal and the planned yield stress (MPa)."""
    planned = weakest_material(material, yield_uncertainty_pct)
    return {"yield_uncertainty_pct": float(yield_uncertainty_pct),
            "nominal_yield_mpa": material.yield_stress_mpa, "planned_yield_mpa": planned.yield_stress_mpa,
            "rule": "springback compensated for the weakest plate of the declared range (yield x (1 - pct/100)): "
                    "every plate within it is under-bent, the corrections add bend (docs/planning.md)"}


def _surface_to_press(fitted, design, press: PressConfig, t: float, material, springback: bool, margin: float):
    """The design surface, or its over-bent version for springback; and the springback report."""
    if not springback:
        return fitted.surface, {"enabled": False}
    reach = float(np.linalg.norm(fitted.frame.to_local(design)[:, :2], axis=1).max()) + margin \
        + press.trim_allowance_mm
    try:
        surface = overbend(fitted.surface, t, material, reach)
    except GeometryError as exc:  # the over-bent arcs do not reach: start the refinement from the design
        return fitted.surface, {"enabled": True, "method": f"design start ({exc})"}
    return surface, overbend_report(surface)


def _design_heights(press: PressConfig, fitted, tf_press_design, active, t: float) -> np.ndarray:
    """The design's mid-surface height at each active punch axis, as the tips would hold it (NaN elsewhere).

    The refinement and the loop's calibrated correction (:mod:`mppf.correct.calibrated`) aim at it.
    """
    gx, gy = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    placed = PlacedSurface(fitted.surface, tf_press_design @ fitted.frame.tf_world_local)
    up, lo = tip_heights(placed, gx[active], gy[active], tip_radius_mm=press.tip_radius_mm, thickness_mm=t)
    return on_grid(press, active, 0.5 * (up.tip_mm + lo.tip_mm))


def _refine(press: PressConfig, upper, lower, active, target, outline, t: float, material):
    """Strokes refined on the plate model, and the refinement's report."""
    refined = refine_strokes(press, StepStrokes(upper, lower, active), target, outline, t, material)
    report = {"virtual_cycles": len(refined.history_mm) - 1, "predicted_max_mm": refined.predicted_max_mm,
              "history_mm": refined.history_mm}
    return refined.upper_mm, refined.lower_mm, report


def plan_summary(job: Job) -> dict:
    """The figures an operator checks before pressing (for tables and ``--json``).

    Returns
    -------
    dict
        Registration, pose, strokes per matrix, steps and plate corners.
    """
    reports = job.reports
    final = job.steps[-1]
    act = final.active

    def matrix(values, limits, flat_mm):
        vals = values[act]
        return {"active": int(act.sum()), "parked": int((~act).sum()), "park_mm": limits.park_mm,
                "min_mm": float(vals.min()), "max_mm": float(vals.max()),
                "limits_mm": [limits.min_mm, limits.max_mm],
                "max_travel_mm": float(np.abs(vals - flat_mm).max())}

    reg = reports.registration or RegistrationReport()
    return {
        "press": job.press.name,
        "matrix": [job.press.rows, job.press.cols],
        "thickness_mm": job.thickness_mm,
        "inputs": reports.inputs.to_doc() if reports.inputs is not None else {},
        "registration": {k: getattr(reg, k) for k in ("method", "rms_mm", "iterations", "rotation_deg",
                                                  "neighbour_strain_p95_pct", "area_mismatch_pct")},
        "pose": reports.pose.to_doc() if reports.pose is not None else {},
        "n_steps": len(job.steps),
        "upper": matrix(final.upper_mm, job.press.upper, job.thickness_mm),
        "lower": matrix(final.lower_mm, job.press.lower, 0.0),
        "max_travel_mm": reports.max_travel_mm,
        "min_gap_mm": None if reports.validation is None else reports.validation.min_gap_mm,
        "max_neighbour_step_mm": None if reports.validation is None else reports.validation.max_neighbour_step_mm,
        "plate_corners_mm": None if reports.plate_corners_mm is None else reports.plate_corners_mm.tolist(),
        "plate_size_mm": None if reports.plate_size_mm is None else reports.plate_size_mm.tolist(),
        "margin_mm": 0.0 if job.layout is None else job.layout.margin_mm,
        "springback": reports.springback_doc(),
    }
