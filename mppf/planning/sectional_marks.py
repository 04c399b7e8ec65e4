"""A section's reference marks, what every section is planned from, and the per-section summary of a sectional job.

The marks are ``docs/sections.md``, item 7; :class:`SectionContext` is what
:func:`mppf.planning.sectional.plan_sectional` hands each section.

Split from :mod:`mppf.planning.sectional` (which re-exports :func:`sections_summary`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.transform import apply_tf, invert_tf
from mppf.geometry.surface import FittedPlate
from mppf.model.job import Job
from mppf.model.material import Material
from mppf.model.press import PressConfig
from mppf.planning.sectional_overbend import WholeTarget
from mppf.planning.sections import mark_punches
from mppf.registration.register import Registration


@dataclass(frozen=True)
class SectionContext:
    """What every section of one plate is planned from (:func:`mppf.planning.sectional.plan_sectional`).

    Attributes
    ----------
    press : PressConfig
        The press.
    fitted : FittedPlate
        The surface every section presses: the whole design's fit (the polynomial, or the B-spline where the
        polynomial misses), in its own frame (mm).
    design : (n, 3) float ndarray
        The design's points, mm.
    flat_file : (m, 3) float ndarray
        The flat file's points as given, mm; paired with ``design`` when ``m == n`` (the unfolding's order).
    registration : Registration
        The design registered onto the flat laid on an unlimited bed (plate coordinates).
    thickness_mm : float
        Plate thickness, mm.
    margin_mm : float
        Trim margin around the net outline, mm.
    material : Material or None
        The nominal material (``options.material``), recorded in each section's layout.
    target : WholeTarget or None
        The whole plate's over-bent target with springback (:mod:`mppf.planning.sectional_overbend`), else None.
    points : (n, 3) float ndarray
        The design's points, or with springback where their material lies on ``target``, mm.
    """

    press: PressConfig
    fitted: FittedPlate
    design: np.ndarray
    flat_file: np.ndarray
    registration: Registration
    thickness_mm: float
    margin_mm: float
    material: Material | None
    target: WholeTarget | None
    points: np.ndarray


def section_marks(press: PressConfig, active, centre, tf_press_flat, placed, fitted, ctx: SectionContext, on_bed):
    """The section's two reference marks: plate x, y; flat-file x, y, z; press x, y; the punches under them.

    ``active`` holds the punches under the net plate, so the marks lie inside the net outline. A mark
    is the material point that lies over its punch **once the section is formed**: the point of the
    pressed surface (``placed``: the design, or the over-bent target) under the punch axis, taken to
    the flat by the paired points (linear interpolation over the pressed surface's own (u, v) of the
    points where the material lies on it).
    Unpaired flats: the flat point under the punch with the plate lying flat. ``ctx`` gives the flat
    file, the design, the points on the pressed surface and the thickness (``SectionContext``).
    """
    punches = mark_punches(active)
    press_xy = np.column_stack([press.punch_x_mm[punches[:, 1]], press.punch_y_mm[punches[:, 0]]])
    flat_file = ctx.flat_file
    flat = apply_tf(invert_tf(tf_press_flat), np.column_stack([press_xy, np.full(2, ctx.thickness_mm / 2.0)]))
    if flat_file.shape == ctx.design.shape:
        from scipy.interpolate import LinearNDInterpolator

        uv = np.column_stack(placed.axis_foot(press_xy[:, 0], press_xy[:, 1]))
        local = fitted.frame.to_local(ctx.points[on_bed])[:, :2]
        formed = LinearNDInterpolator(local, flat_file[on_bed])(uv)
        flat = np.where(np.isfinite(formed), formed, flat)
    plate_xy = apply_tf(tf_press_flat, flat)[:, :2] + np.asarray(centre, dtype=float)
    return plate_xy, flat, press_xy, punches


def sections_summary(job: Job) -> list[dict]:
    """Per section (empty for a single piece): placement, marks, steps, travel, blend and border step."""
    out = []
    for s in job.sections or []:
        out.append({"index": s.index, "cell": list(s.cell), "plate_centre_mm": s.plate_centre_mm.tolist(),
                    "marks_press_mm": s.marks_press_mm.tolist(), "marks_plate_mm": s.marks_plate_mm.tolist(),
                    "mark_punches": (s.mark_punches + job.press.label_base).tolist(), "n_steps": len(s.steps),
                    "max_travel_mm": s.reports.max_travel_mm,
                    "border_step_mm": None if s.transition is None else s.transition.border_step_mm,
                    "blended_punches": None if s.transition is None else s.transition.blended_punches})
    return out
