"""A section's reference marks, and the per-section summary of a sectional job (``docs/sections.md``, item 7).

Split from :mod:`mppf.planning.sectional` (which re-exports :func:`sections_summary`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from mppf.core.transform import apply_tf, invert_tf
from mppf.model.job import Job
from mppf.model.press import PressConfig
from mppf.planning.sections import mark_punches

if TYPE_CHECKING:
    from mppf.planning.sectional import _SectionContext


def section_marks(press: PressConfig, active, centre, tf_press_flat, placed, fitted, ctx: _SectionContext, on_bed):
    """The section's two reference marks: plate x, y; flat-file x, y, z; press x, y; the punches under them.

    ``active`` holds the punches under the net plate, so the marks lie inside the net outline. A mark
    is the material point that lies over its punch **once the section is formed**: the point of the
    pressed surface (``placed``: the design, or the over-bent target) under the punch axis, taken to
    the flat by the paired points (linear interpolation over the pressed surface's own (u, v) of the
    points where the material lies on it).
    Unpaired flats: the flat point under the punch with the plate lying flat. ``ctx`` gives the flat
    file, the design, the points on the pressed surface and the thickness (``_SectionContext``).
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
