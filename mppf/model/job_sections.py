"""The sections of a job file: a plate larger than the bed, formed section by section.

A sectional job (from version 3) holds, besides the job's own keys (which describe section 1,
so every reader of single-piece jobs still finds a valid first section), the list
``"sections"``: each with the shift of the plate for it, its reference marks, its press steps,
its transforms, its plate layout, its planner's reports (:class:`~mppf.model.job_reports.PlanReports`)
and its transition zone (:class:`~mppf.model.job_provenance.TransitionReport`). Single-piece jobs
have no ``"sections"``. See ``docs/sections.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mppf.core.errors import ConfigError, InputError
from mppf.core.transform import tf_from_list, tf_to_list
from mppf.model.job_parts import (
    PlateLayout,
    StepStrokes,
    grid_from_json,
    grid_to_json,
    steps_from_json,
    steps_to_json,
)
from mppf.model.job_provenance import TransitionReport
from mppf.model.job_reports import PlanReports
from mppf.model.press import PressConfig


@dataclass(frozen=True, eq=False)
class Section:
    """One section of a plate formed section by section.

    Plate coordinates: the flat plate as laid on an unlimited bed (long side along press x,
    centred on the origin, bottom skin at z = 0); a plate point p lies at press x, y
    ``p_xy + plate_centre_mm`` in this section.

    Attributes
    ----------
    index : int
        1-based, the order in which the sections are pressed.
    cell : (int, int)
        (along, across) position of the section in the split, from 0.
    plate_centre_mm : (2,) float
        Press x, y of the plate centre for this section (the shift of the plate).
    marks_plate_mm : (2, 2) float
        The section's two reference marks in plate coordinates (x, y on the flat).
    marks_flat_mm : (2, 3) float
        The same marks in the flat file's coordinates (for the DXF of the flat).
    marks_press_mm : (2, 2) float
        Where the marks must lie on the bed (over the punch axes ``mark_punches``).
    mark_punches : (2, 2) int
        (row, col) from 0 of the punches the marks lie over.
    steps : list of StepStrokes
    tf_press_design, tf_press_flat : (4, 4) float
    layout : PlateLayout
        The plate on the press in this section.
    own_weight : (rows, cols) float
        Weight of this section's own stroke correction at each active punch (1 outside the
        transition zones, below 1 where it blends with the earlier sections; NaN parked).
    reports : PlanReports
        The section's pose, validation, step and punch counts and plate corners.
    transition : TransitionReport or None
        The section's transition zone and the step where it meets the earlier sections.
    """

    index: int
    cell: tuple[int, int]
    plate_centre_mm: np.ndarray
    marks_plate_mm: np.ndarray
    marks_flat_mm: np.ndarray
    marks_press_mm: np.ndarray
    mark_punches: np.ndarray
    steps: list[StepStrokes]
    tf_press_design: np.ndarray
    tf_press_flat: np.ndarray
    layout: PlateLayout
    own_weight: np.ndarray
    reports: PlanReports = field(default_factory=PlanReports)
    transition: TransitionReport | None = None

    def shift_from_mm(self, previous: Section) -> np.ndarray:
        """(2,) float: how far the plate moves on the bed from ``previous`` to this section (mm)."""
        return np.asarray(self.plate_centre_mm, dtype=float) - np.asarray(previous.plate_centre_mm, dtype=float)

    def to_dict(self) -> dict:
        """The section's entry in the job document."""
        return {
            "index": int(self.index),
            "cell": [int(c) for c in self.cell],
            "plate_centre_mm": np.asarray(self.plate_centre_mm, dtype=float).tolist(),
            "marks": {"plate_mm": np.asarray(self.marks_plate_mm, dtype=float).tolist(),
                      "flat_mm": np.asarray(self.marks_flat_mm, dtype=float).tolist(),
                      "press_mm": np.asarray(self.marks_press_mm, dtype=float).tolist(),
                      "punches": np.asarray(self.mark_punches, dtype=int).tolist()},
            "tf_press_design": tf_to_list(self.tf_press_design),
            "tf_press_flat": tf_to_list(self.tf_press_flat),
            "plate": self.layout.to_dict(),
            "own_weight": grid_to_json(self.own_weight),
            "steps": steps_to_json(self.steps),
            **self.reports.to_doc(),
            **({} if self.transition is None else {"transition": self.transition.to_doc()}),
        }


SECTION_KEYS = {"index", "cell", "plate_centre_mm", "marks", "tf_press_design", "tf_press_flat", "plate",
                "own_weight", "steps"}


def section_from_dict(doc, press: PressConfig, source: str) -> Section:
    """Inverse of :meth:`Section.to_dict`, checked against the press.

    Raises
    ------
    ConfigError
        A missing or malformed key (named with the section).
    """
    if not isinstance(doc, dict) or not SECTION_KEYS <= set(doc):
        missing = sorted(SECTION_KEYS - set(doc)) if isinstance(doc, dict) else sorted(SECTION_KEYS)
        raise ConfigError(f"{source}: the section lacks {', '.join(missing)}",
                          hint="re-plan the plate with 'mppf plan'")
    reports = PlanReports.from_doc(doc, f"{source}:")
    transition = None if doc.get("transition") is None else TransitionReport.from_doc(doc["transition"],
                                                                                       f"{source}: transition")
    try:
        marks = doc["marks"]
        section = Section(
            index=int(doc["index"]), cell=tuple(int(c) for c in doc["cell"]),
            plate_centre_mm=_array(doc["plate_centre_mm"], (2,)),
            marks_plate_mm=_array(marks["plate_mm"], (2, 2)), marks_flat_mm=_array(marks["flat_mm"], (2, 3)),
            marks_press_mm=_array(marks["press_mm"], (2, 2)),
            mark_punches=np.asarray(marks["punches"], dtype=int).reshape(2, 2),
            steps=steps_from_json(doc["steps"], press, source),
            tf_press_design=tf_from_list(doc["tf_press_design"], "tf_press_design"),
            tf_press_flat=tf_from_list(doc["tf_press_flat"], "tf_press_flat"),
            layout=PlateLayout.from_dict(doc["plate"], source),
            own_weight=grid_from_json(doc["own_weight"]), reports=reports, transition=transition)
    except InputError as exc:
        raise ConfigError(f"{source}: {exc.message}", hint="re-plan the plate with 'mppf plan'") from None
    except (KeyError, TypeError, ValueError, OverflowError) as exc:
        raise ConfigError(f"{source}: the section is malformed ({type(exc).__name__}: {exc})",
                          hint="re-plan the plate with 'mppf plan'") from None
    if section.own_weight is None or section.own_weight.shape != press.shape:
        raise ConfigError(f"{source}: own_weight must be a grid of the press's {press.rows} x {press.cols} punches")
    return section


def sections_from_json(docs, press: PressConfig, source: str) -> list[Section]:
    """The job's ``"sections"`` list, numbered 1..n in order.

    Raises
    ------
    ConfigError
        Not a non-empty list, or sections out of order.
    """
    if not isinstance(docs, list) or not docs:
        raise ConfigError(f"{source}: 'sections' must be a non-empty list", hint="re-plan the plate with 'mppf plan'")
    sections = [section_from_dict(d, press, f"{source} section {k}") for k, d in enumerate(docs, start=1)]
    if [s.index for s in sections] != list(range(1, len(sections) + 1)):
        raise ConfigError(f"{source}: the sections are numbered {[s.index for s in sections]}, expected 1..n in order")
    return sections


def _array(values, shape) -> np.ndarray:
    arr = np.asarray(values, dtype=float)
    if arr.shape != shape or not np.all(np.isfinite(arr)):
        raise ValueError(f"expected {shape} finite numbers, got shape {arr.shape}")
    return arr
