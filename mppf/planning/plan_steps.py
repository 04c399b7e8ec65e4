"""The planner's shared steps: what :func:`mppf.planning.plan.plan_job` and the sectional planner
(:mod:`mppf.planning.sectional`) both do to a plate.

Each is one stage of the planner in ``docs/planning.md``: the inputs checked, the punches under the
plate, the pose of least travel, the values on the punch grid, the press steps, the trim check and
the reports a job keeps (:class:`~mppf.model.job_reports.PlanReports`). Lengths in mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.errors import GeometryError, InputError, LimitError
from mppf.core.polygon import contains, distance_outside
from mppf.core.transform import as_points, rotation_angle_deg
from mppf.core.validate import check_number
from mppf.model.job_reports import (
    PlanInputs,
    PlanReports,
    PoseReport,
    RegistrationReport,
    SpringbackReport,
    SurfaceFitReport,
    ValidationReport,
)
from mppf.model.press import PressConfig
from mppf.planning.contact import PlacedSurface
from mppf.planning.pose import optimise_pose
from mppf.planning.steps import MAX_STEPS, split_steps

MAX_MARGIN_MM = 500.0
"""Largest trim margin accepted (mm)."""


def check_plan_inputs(design_points, flat_points, press: PressConfig, thickness_mm, steps, material, springback,
                      margin_mm):
    """Every option of a plan checked before any work.

    Parameters
    ----------
    design_points, flat_points : (n, 3) and (k, 3) float, mm
        The design and its flat plate.
    press : PressConfig
    thickness_mm : float
        Plate thickness, > 0.
    steps : int or None
        Number of press steps asked for, in [1, ``MAX_STEPS``], or None (the fewest).
    material : Material or None
        Needed when ``springback``.
    springback : bool
    margin_mm : float or None
        Trim margin in [0, :data:`MAX_MARGIN_MM`]; None: the press's ``margin_mm``.

    Returns
    -------
    design : (n, 3) float, mm
    flat : (k, 3) float, mm
    thickness_mm : float
    margin_mm : float

    Raises
    ------
    InputError
        Points that are not (n, 3) numbers, a thickness, step count or margin out of range, or
        springback without a material.
    """
    design = as_points(design_points, "design points")
    flat = as_points(flat_points, "flat points")
    t = check_number("the plate thickness", thickness_mm, low=0.0, low_open=True, unit="mm",
                     hint="give e.g. --thickness 20")
    if springback and material is None:
        raise InputError("springback compensation needs the plate material",
                         hint="give --material steel|ah36 or --youngs/--poisson/--yield")
    if steps is not None:
        check_number("the number of steps", steps, low=1, high=MAX_STEPS, integer=True,
                     hint="leave --steps out to get the fewest steps within the dimpling limit")
    margin = check_number("the trim margin", press.margin_mm if margin_mm is None else margin_mm, low=0.0,
                          high=MAX_MARGIN_MM, unit="mm",
                          hint="give e.g. --margin 100 (or 0 to cut the plate to its net outline)")
    return design, flat, float(t), float(margin)


def active_punches(press: PressConfig, outline_xy) -> np.ndarray:
    """The punch axes inside the plate as cut.

    Parameters
    ----------
    press : PressConfig
    outline_xy : (k, 2) float, mm
        The plate's outline in press x, y.

    Returns
    -------
    (rows, cols) bool

    Raises
    ------
    LimitError
        The plate covers no punch axis.
    """
    gx, gy = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    active = contains(outline_xy, np.column_stack([gx.ravel(), gy.ravel()])).reshape(press.shape)
    if not active.any():
        raise LimitError("the plate covers no punch axis", hint="check the plate size and the press pitch")
    return active


def least_travel_pose(press: PressConfig, placed: PlacedSurface, active, t: float):
    """The pose of least travel of the active punches, tilted about the plate centre.

    Parameters
    ----------
    press : PressConfig
    placed : PlacedSurface
        The surface to press, placed on the bed.
    active : (rows, cols) bool
    t : float
        Plate thickness, mm.

    Returns
    -------
    Pose
        As :func:`mppf.planning.pose.optimise_pose` (tip heights of the active punches, mm).
    """
    gx, gy = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    rows, cols = np.nonzero(active)
    return optimise_pose(placed, gx[active], gy[active], [f"[{r},{c}]" for r, c in zip(rows, cols)], press, t,
                         np.array([0.0, 0.0, t / 2.0]))


def on_grid(press: PressConfig, active, values) -> np.ndarray:
    """Values of the active punches on the punch grid.

    Parameters
    ----------
    press : PressConfig
    active : (rows, cols) bool
    values : (n_active,) float
        In the row-major order of ``active``.

    Returns
    -------
    (rows, cols) float
        ``values`` at the active punches, NaN elsewhere.
    """
    grid = np.full(press.shape, np.nan)
    grid[active] = values
    return grid


def steps_within_limit(upper, lower, active, press: PressConfig, t: float, n_steps: int):
    """The press steps from flat to the final strokes, refused beyond ``MAX_STEPS``.

    Parameters
    ----------
    upper, lower : (rows, cols) float, mm
        Final tip heights of both matrices (NaN at inactive punches).
    active : (rows, cols) bool
    press : PressConfig
    t : float
        Plate thickness, mm.
    n_steps : int

    Returns
    -------
    list of StepStrokes
        As :func:`mppf.planning.steps.split_steps`.

    Raises
    ------
    LimitError
        More than ``MAX_STEPS`` steps.
    """
    if n_steps > MAX_STEPS:
        raise LimitError(f"the plate needs {n_steps} press steps to keep within the dimpling limit of "
                         f"{press.max_neighbour_diff_mm:g} mm, more than the {MAX_STEPS} one job may hold",
                         hint="check [forming] max_neighbour_diff_mm in the press description")
    return split_steps(upper, lower, active, t, int(n_steps))


@dataclass(frozen=True, eq=False)
class PlannedPiece:
    """What the planner found for one piece, from which :func:`planner_reports` writes its reports.

    Attributes
    ----------
    fitted : FittedPlate
        The fitted design surface (``kind``, ``degree``, ``rms_mm``, ``max_abs_mm``).
    registration : Registration
        The design registered onto the flat (``to_dict()``, ``tf`` (4, 4)).
    belongs : dict
        The checks that the flat is the design's unfolding (added to the registration report).
    placement : FlatPlacement
        The flat plate on the bed (``corners_mm`` (4, 3), ``size_mm`` (2,), mm).
    pose : Pose
        The pose of least travel (``tilt_x_deg``, ``tilt_y_deg``, ``offset_mm``).
    upper_mm, lower_mm : (rows, cols) float, mm
        Final tip heights of both matrices (NaN at inactive punches).
    active : (rows, cols) bool
    thickness_mm : float
        Plate thickness, mm.
    validation : dict or ValidationReport
        The validation of the steps.
    n_steps : int
    springback : dict or SpringbackReport
        The springback planning's report.
    inputs : PlanInputs, dict or None
        The files planned from.
    """

    fitted: object
    registration: object
    belongs: dict
    placement: object
    pose: object
    upper_mm: np.ndarray
    lower_mm: np.ndarray
    active: np.ndarray
    thickness_mm: float
    validation: object
    n_steps: int
    springback: object
    inputs: object = None


def planner_reports(piece: PlannedPiece) -> PlanReports:
    """The planner's reports stored in the job (:class:`~mppf.model.job_reports.PlanReports`).

    Parameters
    ----------
    piece : PlannedPiece
        The planner's intermediate results of the piece, each kept as its report.

    Returns
    -------
    PlanReports
        The pose's ``max_travel_mm`` is the largest ``|tip height - flat-plate tip height|`` over the
        active punches of both matrices (upper t, lower 0), mm.
    """
    registration_doc = {**piece.registration.to_dict(), **piece.belongs,
                        "rotation_deg": rotation_angle_deg(piece.registration.tf)}
    active, t = piece.active, piece.thickness_mm
    travel = float(max(np.abs(piece.upper_mm[active] - t).max(), np.abs(piece.lower_mm[active]).max()))
    fitted, pose = piece.fitted, piece.pose
    return PlanReports(
        surface_fit=SurfaceFitReport(surface_kind=fitted.kind, surface_degree=fitted.degree,
                                     surface_fit_rms_mm=fitted.rms_mm, surface_fit_max_mm=fitted.max_abs_mm),
        registration=RegistrationReport.from_doc(registration_doc, "the registration report"),
        pose=PoseReport(tilt_x_deg=pose.tilt_x_deg, tilt_y_deg=pose.tilt_y_deg, offset_mm=pose.offset_mm,
                        max_travel_mm=travel,
                        travel_definition="largest |tip height - flat-plate tip height| (upper t, lower 0)"),
        validation=as_validation(piece.validation),
        plate_corners_mm=np.asarray(piece.placement.corners_mm, dtype=float),
        plate_size_mm=np.asarray(piece.placement.size_mm, dtype=float), n_active=int(active.sum()),
        n_steps=int(piece.n_steps), inputs=PlanInputs.of(piece.inputs or {}),
        springback=as_springback(piece.springback),
    )


def section_reports(pose, max_travel_mm: float, validation, n_steps: int, active, corners_mm) -> PlanReports:
    """The reports of one section of a sectional plan: its pose, validation, counts and plate corners.

    Parameters
    ----------
    pose : Pose
        The section's pose of least travel (``tilt_x_deg``, ``tilt_y_deg``, ``offset_mm``).
    max_travel_mm : float
        The section's largest travel, mm.
    validation : dict or ValidationReport
    n_steps : int
    active : (rows, cols) bool
    corners_mm : (4, 3) float
        The plate's corners on the bed in this section, mm.
    """
    return PlanReports(pose=PoseReport(tilt_x_deg=pose.tilt_x_deg, tilt_y_deg=pose.tilt_y_deg,
                                       offset_mm=pose.offset_mm, max_travel_mm=float(max_travel_mm)),
                       validation=as_validation(validation), plate_corners_mm=np.asarray(corners_mm, dtype=float),
                       n_active=int(np.sum(active)), n_steps=int(n_steps))


def as_validation(validation) -> ValidationReport:
    """The validation report of :func:`mppf.planning.validate.validate_steps` (its dict, with the planner's
    additions) as a :class:`~mppf.model.job_reports.ValidationReport`."""
    if isinstance(validation, ValidationReport):
        return validation
    return ValidationReport.from_doc(validation, "the validation report")


def as_springback(report) -> SpringbackReport:
    """The springback report (a dict as the planner builds it, or already typed) as a
    :class:`~mppf.model.job_reports.SpringbackReport`."""
    if isinstance(report, SpringbackReport):
        return report
    return SpringbackReport.from_doc(report, "the springback report")


def check_trim(contact_xy_mm, outline_xy, press: PressConfig) -> float:
    """Largest distance of a ball contact past the plate edge; refused beyond the trim allowance.

    Parameters
    ----------
    contact_xy_mm : (n, 2) float, mm
        The ball contacts in press x, y.
    outline_xy : (k, 2) float, mm
        The plate as cut.
    press : PressConfig

    Returns
    -------
    float
        The distance, mm (0 when every contact is on the plate).

    Raises
    ------
    GeometryError
        Beyond the press's ``trim_allowance_mm``.
    """
    beyond = float(distance_outside(outline_xy, contact_xy_mm).max())
    if beyond > press.trim_allowance_mm:
        raise GeometryError(
            f"a punch ball touches the design surface {beyond:.0f} mm past the plate edge, beyond the "
            f"press's trim allowance of {press.trim_allowance_mm:g} mm",
            hint="raise [forming] trim_allowance_mm in the press description if the surface may be "
                 "extended that far",
        )
    return beyond


def overbend_report(surface) -> dict:
    """The springback report of an over-bent surface (the dict of a job's ``springback`` report).

    Parameters
    ----------
    surface : OverbentSurface or alike
        Has ``target_k``, ``loaded_k`` (2,) principal curvatures in 1/mm and ``directions`` (2, 2).

    Returns
    -------
    dict
        The target and loaded principal radii (mm, None for a flat direction) and their directions.
    """
    def radii(k):
        return [None if abs(v) < 1e-12 else float(1.0 / v) for v in k]

    return {
        "enabled": True,
        "method": "principal arcs at the plate centre replaced by over-bent arcs (docs/planning.md)",
        "target_radii_mm": radii(surface.target_k),
        "loaded_radii_mm": radii(surface.loaded_k),
        "directions_uv": surface.directions.tolist(),
    }
