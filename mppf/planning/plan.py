"""Stroke planning: a design surface and its flat plate -> strokes of both punch matrices.

:func:`plan_job` is the whole planner as a short sequence of calls; each stage is a
small module: :mod:`mppf.planning.placement` (flat on the bed, registration),
:mod:`mppf.planning.belongs` (the flat is the design's), :mod:`mppf.planning.pose` (offset and
tilt of least travel), :mod:`mppf.planning.contact` (exact ball-tip contact),
:mod:`mppf.planning.overbend` (springback pre-compensation),
:mod:`mppf.forming.precompensate` (its refinement on the plate model),
:mod:`mppf.planning.steps` (multi-step forming), :mod:`mppf.planning.validate` (the one job validator). The math is in
``docs/planning.md``; the job file in ``docs/file-formats.md``.
"""

from __future__ import annotations

import numpy as np

from mppf.core.errors import GeometryError
from mppf.core.polygon import convex_outline, offset_convex
from mppf.core.progress import NULL_REPORTER
from mppf.core.transform import apply_tf
from mppf.correct.virtual_cycles import refine_strokes
from mppf.forming.material import check_yield_uncertainty, weakest_material
from mppf.geometry.surface import fit_plate
from mppf.model.job import Job
from mppf.model.job_parts import PlateLayout
from mppf.model.material import Material
from mppf.model.press import PressConfig
from mppf.planning.belongs import check_flat_belongs, design_area_mm2
from mppf.planning.contact import PlacedSurface, tip_heights
from mppf.planning.overbend import overbend
from mppf.planning.placement import place_flat, register_design
from mppf.planning.plan_steps import (
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

SURFACE_KIND = "poly"
SURFACE_DEGREE = 4


def plan_job(design_points, flat_points, press: PressConfig, thickness_mm: float, *, steps: int | None = None,
             material: Material | None = None, springback: bool = False, design_faces=None,
             reporter=NULL_REPORTER, inputs: dict | None = None, margin_mm: float | None = None,
             yield_uncertainty_pct: float = 0.0) -> Job:
    """Plan the strokes of every punch of both matrices for one plate.

    Parameters
    ----------
    design_points : (n, 3) float, mm
        The design (curved) plate's mid-surface, any coordinates (e.g. hull).
    flat_points : (k, 3) float, mm
        Its unfolded (flat) plate; with k == n the points are taken as paired with
        the design's, in the same order (as :func:`mppf.geometry.unfold.unfold` gives them).
    press : PressConfig
    thickness_mm : float
        Plate thickness t, > 0.
    steps : int, optional
        Number of press steps; by default the fewest within the dimpling limit.
    material : Material, optional
        Needed for ``springback``.
    springback : bool
        Pre-compensate springback: over-bend the principal arcs, then refine the strokes
        by virtual press cycles on the plate model with the nominal material
        (:func:`mppf.correct.virtual_cycles.refine_strokes`).
    design_faces : (m, 3) int, optional
        Mesh triangles of the design (better fold and area checks).
    reporter : Reporter
    inputs : dict, optional
        ``{"design": {"path", "sha256"}, "flat": {...}}`` recorded in the job.
    margin_mm : float, optional
        Trim margin: the flat plate is cut with this excess band around its net outline
        (trimmed after forming), so punches under the band are used too; default the
        press's ``[forming] margin_mm``. The design surface is extended smoothly over it.
    yield_uncertainty_pct : float
        With ``springback``: the declared scatter of the yield stress (+- %, in [0, 50)). The
        springback is compensated for the weakest plate of the range (:func:`first_press_material`),
        so every plate within it is under-bent, never over-bent; the layout keeps the nominal
        material and ``extra["springback"]["first_press"]`` records what was assumed.

    Returns
    -------
    Job
        Validated; its ``layout`` holds the plate as cut (margin included), the net
        outline, the margin, the reference corner, the design heights at the punches and
        the material; ``extra`` the reports ``registration``, ``validation``,
        ``plate_corners_mm``, ``pose``, ``inputs``, ``springback``, ``n_steps``.

    Raises
    ------
    InputError
        Bad thickness, step count or points; GeometryError for a flat that does not
        belong to the design; LimitError for a plate that does not fit or strokes
        that cannot be kept inside the press limits (nothing is planned).
    """
    design, flat, t, margin = check_plan_inputs(design_points, flat_points, press, thickness_mm, steps, material,
                                                springback, margin_mm)
    planned_material = first_press_material(material, springback, yield_uncertainty_pct)
    # 1. lay the flat plate on the bed: centred, long side along x, bottom skin at z = 0
    reporter.info("placing the flat plate on the bed")
    placement = place_flat(flat, press, t)
    # 2. fit the design in its own frame; register it onto the flat on the bed; the flat must be its unfolding
    fitted = fit_plate(design, degree=SURFACE_DEGREE, kind=SURFACE_KIND, faces=design_faces)
    reporter.info("registering the design onto the flat plate")
    registration = register_design(design, placement.flat_press_mm, reporter=reporter)
    if registration.ambiguous_start:
        reporter.info("the plate is nearly symmetric: check that the plate lies the right way round "
                      "(registration start was ambiguous)")
    belongs = check_flat_belongs(design, placement.flat_press_mm, registration.method == "paired",
                                 design_area_mm2(fitted, design, design_faces))
    # 3. the surface to press: the design, over-bent for springback (of the weakest plate declared) if asked
    surface, springback_report = _surface_to_press(fitted, design, press, t, planned_material, springback, margin)
    # 4. active punches: axes inside the plate as cut (the design's outline seen from above, grown by the margin)
    design_press = apply_tf(registration.tf, design)
    outline_xy = offset_convex(convex_outline(design_press[:, :2], "the placed design"), margin)
    active = active_punches(press, outline_xy)
    # 5. strokes: exact ball contact, with the offset and tilt of least travel
    reporter.info(f"solving the contact of {2 * int(active.sum())} punches")
    placed = PlacedSurface(surface, registration.tf @ fitted.frame.tf_world_local)
    pose = least_travel_pose(press, placed, active, t)
    upper, lower = on_grid(press, active, pose.upper_mm), on_grid(press, active, pose.lower_mm)
    tf_press_design = pose.tf_adjust @ registration.tf
    net_outline = convex_outline(apply_tf(pose.tf_adjust, design_press)[:, :2], "the placed design")
    outline = offset_convex(net_outline, margin)
    # 6. the design's mid-surface height at each active punch (the refinement's and the loop's target)
    target = _design_heights(press, fitted, tf_press_design, active, t)
    # 7. springback: virtual press cycles on the plate model (the planned material) against the design
    if springback:
        reporter.info("refining the springback pre-compensation on the plate model")
        upper, lower, springback_report["refinement"] = _refine(press, upper, lower, active, target, outline, t,
                                                                planned_material)
        springback_report["first_press"] = first_press_report(material, yield_uncertainty_pct)
    # 8. press steps from flat to the target, within the dimpling limit
    n_steps = steps if steps is not None else steps_needed(upper, lower, active, press, t)
    step_list = steps_within_limit(upper, lower, active, press, t, n_steps)
    # 9. validate everything before a job exists
    validation = validate_steps(step_list, press, t)
    validation["contact_exact_fraction"] = float(np.mean(pose.exact))
    validation["contact_beyond_edge_mm"] = check_trim(pose.contact_xy_mm, outline_xy, press)
    extra = planner_reports(fitted, registration, belongs, pose, upper, lower, active, t, validation, placement,
                            int(n_steps), inputs, springback_report)
    layout = PlateLayout(outline_mm=outline, net_outline_mm=net_outline, margin_mm=margin, design_mid_mm=target,
                         material=material)
    return Job(press=press, thickness_mm=t, steps=step_list, tf_press_design=tf_press_design,
               tf_press_flat=placement.tf_press_flat, layout=layout, extra=extra)


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
    """What the first press assumed (``extra["springback"]["first_press"]``): the declared scatter, the
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
    refined = refine_strokes(press, upper, lower, active, target, outline, t, material)
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
    extra = job.extra
    final = job.steps[-1]
    act = final.active

    def matrix(values, limits, flat_mm):
        vals = values[act]
        return {"active": int(act.sum()), "parked": int((~act).sum()), "park_mm": limits.park_mm,
                "min_mm": float(vals.min()), "max_mm": float(vals.max()),
                "limits_mm": [limits.min_mm, limits.max_mm],
                "max_travel_mm": float(np.abs(vals - flat_mm).max())}

    reg = extra.get("registration", {})
    return {
        "press": job.press.name,
        "matrix": [job.press.rows, job.press.cols],
        "thickness_mm": job.thickness_mm,
        "inputs": extra.get("inputs", {}),
        "registration": {k: reg.get(k) for k in ("method", "rms_mm", "iterations", "rotation_deg",
                                                  "neighbour_strain_p95_pct", "area_mismatch_pct")},
        "pose": extra.get("pose", {}),
        "n_steps": len(job.steps),
        "upper": matrix(final.upper_mm, job.press.upper, job.thickness_mm),
        "lower": matrix(final.lower_mm, job.press.lower, 0.0),
        "max_travel_mm": extra.get("pose", {}).get("max_travel_mm"),
        "min_gap_mm": extra.get("validation", {}).get("min_gap_mm"),
        "max_neighbour_step_mm": extra.get("validation", {}).get("max_neighbour_step_mm"),
        "plate_corners_mm": extra.get("plate_corners_mm"),
        "plate_size_mm": extra.get("plate_size_mm"),
        "margin_mm": 0.0 if job.layout is None else job.layout.margin_mm,
        "springback": extra.get("springback", {"enabled": False}),
    }
