"""The planner's reports in a job: what it found while planning a plate (or one section of it).

Each report is a frozen :class:`~mppf.model.job_record.DocRecord`, written under its key at the
top level of the job file (and of each section); :class:`PlanReports` gathers those of one piece.
Other stages read these typed fields (the press and batch summaries the pose's travel and the
validation's gaps, the job checks the validation and step count, ``mppf unfold --job`` the design's
hash, the loop the springback report) and never keys of a dict. See ``docs/file-formats.md``
("Keys the planner adds"). Lengths in mm, angles in degrees.
"""

# ruff: noqa: RUF009 - the field helpers of mppf.model.job_record return dataclasses.field(default=None, ...)
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.model.job_record import (
    DocRecord,
    array,
    boolean,
    integer,
    number,
    numbers,
    record,
    text,
)


@dataclass(frozen=True)
class SurfaceFitReport(DocRecord):
    """How the design surface was fitted (the ``"planner"`` block).

    Attributes
    ----------
    surface_kind : str
        ``poly`` or ``spline``.
    surface_degree : int
    surface_fit_rms_mm, surface_fit_max_mm : float
        Residuals of the fit at the design points, mm.
    """

    surface_kind: str | None = text()
    surface_degree: int | None = integer()
    surface_fit_rms_mm: float | None = number()
    surface_fit_max_mm: float | None = number()


@dataclass(frozen=True)
class RegistrationReport(DocRecord):
    """How the design was put on the flat plate, and the checks that the flat is its unfolding.

    Attributes
    ----------
    method : str
        ``paired`` (closed form on the unfolding's point pairs) or an ICP method (``point``).
    rms_mm : float
        RMS distance after registration, mm.
    iterations : int
    rotation_deg : float
        Rotation angle of the registration, degrees.
    ambiguous_start : bool
        True for a nearly symmetric plate (which way round it lies must be checked).
    neighbour_strain_p95_pct : float or None
        95th percentile of the change of neighbouring point distances between flat and design, %
        (paired only).
    area_mismatch_pct : float
        Area of the flat against the design's, %.
    details : dict
        The registration's other keys (transform, convergence, history, notes, ...), as the
        registration wrote them; free-form, read by no stage.
    """

    REST = "details"
    method: str | None = text()
    rms_mm: float | None = number()
    iterations: int | None = integer()
    rotation_deg: float | None = number()
    ambiguous_start: bool | None = boolean()
    neighbour_strain_p95_pct: float | None = number()
    area_mismatch_pct: float | None = number()
    details: dict | None = None


@dataclass(frozen=True)
class PoseReport(DocRecord):
    """The pose of least travel of the plate on the press.

    Attributes
    ----------
    tilt_x_deg, tilt_y_deg : float
        Rotation about press x and y through the plate centre, degrees.
    offset_mm : float
        Vertical shift, mm.
    max_travel_mm : float
        Largest ``|tip height - flat-plate tip height|`` over both matrices (upper t, lower 0), mm.
    travel_definition : str or None
        That definition in words (single-piece jobs).
    """

    tilt_x_deg: float | None = number()
    tilt_y_deg: float | None = number()
    offset_mm: float | None = number()
    max_travel_mm: float | None = number()
    travel_definition: str | None = text()


@dataclass(frozen=True)
class ValidationReport(DocRecord):
    """The validation of the planned steps (:func:`mppf.planning.validate.validate_steps`).

    Attributes
    ----------
    passed : bool
        Always True in a written job.
    n_steps : int
    min_gap_mm : float or None
        Smallest upper-minus-lower tip gap, mm (None: no active punch).
    max_neighbour_step_mm : float
        Largest change of a neighbour difference in one step, mm.
    dimpling_limit_mm : float
    upper_range_mm, lower_range_mm : (2,) float or None
        Range of the final tip heights, mm.
    upper_limits_mm, lower_limits_mm : (2,) float
        The press's stroke limits, mm.
    contact_exact_fraction : float or None
        Share of punch pairs whose contact Newton solved exactly (single piece).
    contact_beyond_edge_mm : float or None
        How far past the plate edge a ball touches the extended surface, mm.
    """

    passed: bool | None = boolean()
    n_steps: int | None = integer()
    min_gap_mm: float | None = number()
    max_neighbour_step_mm: float | None = number()
    dimpling_limit_mm: float | None = number()
    upper_range_mm: tuple | None = numbers()
    lower_range_mm: tuple | None = numbers()
    upper_limits_mm: tuple | None = numbers()
    lower_limits_mm: tuple | None = numbers()
    contact_exact_fraction: float | None = number()
    contact_beyond_edge_mm: float | None = number()


@dataclass(frozen=True)
class RefinementReport(DocRecord):
    """The virtual press cycles that refined the springback strokes on the plate model.

    Attributes
    ----------
    virtual_cycles : int
    predicted_max_mm : float
        Largest predicted form error after them, mm.
    history_mm : (k,) float
        The predicted largest error cycle by cycle, mm.
    """

    virtual_cycles: int | None = integer()
    predicted_max_mm: float | None = number()
    history_mm: tuple | None = numbers()


@dataclass(frozen=True)
class FirstPressReport(DocRecord):
    """What the first press assumed: the yield stress the springback was compensated for.

    Attributes
    ----------
    yield_uncertainty_pct : float
        The declared scatter of the yield stress, +- %.
    nominal_yield_mpa, planned_yield_mpa : float
        The nominal yield stress and the weakest of the range, planned with, MPa.
    rule : str
    """

    yield_uncertainty_pct: float | None = number()
    nominal_yield_mpa: float | None = number()
    planned_yield_mpa: float | None = number()
    rule: str | None = text()


@dataclass(frozen=True)
class SpringbackReport(DocRecord):
    """The springback pre-compensation (``enabled`` False: none).

    Attributes
    ----------
    enabled : bool
    method : str or None
    target_radii_mm, loaded_radii_mm : (2,) float or None
        Principal radii at the plate centre before and after over-bending, mm (None: flat).
    directions_uv : (2, 2) float or None
        The principal directions.
    refinement : RefinementReport or None
    first_press : FirstPressReport or None
    """

    enabled: bool | None = boolean()
    method: str | None = text()
    target_radii_mm: tuple | None = numbers()
    loaded_radii_mm: tuple | None = numbers()
    directions_uv: tuple | None = numbers()
    refinement: RefinementReport | None = record(RefinementReport)
    first_press: FirstPressReport | None = record(FirstPressReport)


@dataclass(frozen=True)
class InputFile(DocRecord):
    """An input file of the plan: where it was and the SHA-256 (hex) of its bytes."""

    path: str | None = text()
    sha256: str | None = text()


@dataclass(frozen=True)
class PlanInputs(DocRecord):
    """The files a job was planned from.

    Attributes
    ----------
    design, flat, press : InputFile or None
    units : str or None
        The units of the input files (``mm`` or ``m``).
    """

    design: InputFile | None = record(InputFile)
    flat: InputFile | None = record(InputFile)
    press: InputFile | None = record(InputFile)
    units: str | None = text()

    @classmethod
    def of(cls, inputs) -> PlanInputs | None:
        """The inputs as given to the planner: a :class:`PlanInputs`, its JSON dict, or None."""
        if inputs is None or isinstance(inputs, PlanInputs):
            return inputs
        return cls.from_doc({k: {**v, "path": str(v["path"])} if isinstance(v, dict) and "path" in v else v
                             for k, v in inputs.items()}, "the plan's inputs")


@dataclass(frozen=True, eq=False)
class PlanReports(DocRecord):
    """The planner's reports of one piece (the job, or one of its sections), at the top level of its block.

    Attributes
    ----------
    surface_fit : SurfaceFitReport or None
        Key ``"planner"``.
    registration : RegistrationReport or None
    pose : PoseReport or None
    validation : ValidationReport or None
    plate_corners_mm : (4, 3) float or None
        Where the operator puts the plate: the flat plate's corners on the bed (z = 0, the bottom
        skin) in the order (-x, -y), (+x, -y), (+x, +y), (-x, +y), mm.
    plate_size_mm : (2,) float or None
        The x, y extent of the flat plate on the bed, mm.
    n_active : int or None
        Active punch pairs.
    n_steps : int or None
        Press steps planned.
    inputs : PlanInputs or None
    springback : SpringbackReport or None
    """

    surface_fit: SurfaceFitReport | None = record(SurfaceFitReport, "planner")
    registration: RegistrationReport | None = record(RegistrationReport)
    pose: PoseReport | None = record(PoseReport)
    validation: ValidationReport | None = record(ValidationReport)
    plate_corners_mm: np.ndarray | None = array((4, 3))
    plate_size_mm: np.ndarray | None = array((2,))
    n_active: int | None = integer()
    n_steps: int | None = integer()
    inputs: PlanInputs | None = record(PlanInputs)
    springback: SpringbackReport | None = record(SpringbackReport)

    @property
    def max_travel_mm(self) -> float | None:
        """The pose's largest travel, mm (None when the job has no pose report)."""
        return None if self.pose is None else self.pose.max_travel_mm

    @property
    def design_sha256(self) -> str | None:
        """SHA-256 of the design file planned from (None when not recorded)."""
        design = None if self.inputs is None else self.inputs.design
        return None if design is None else design.sha256

    def springback_doc(self) -> dict:
        """The springback report as JSON (``{"enabled": False}`` when there is none)."""
        return {"enabled": False} if self.springback is None else self.springback.to_doc()
