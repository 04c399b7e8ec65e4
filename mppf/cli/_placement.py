"""Where to lay the plate, as ``mppf press`` and ``mppf loop`` print it before the press moves.

The corners of the plate as cut (with its trim margin) in press mm, corner A first (the
corner the reference mark is on: the mark is the corner of the plate as cut), then
counter-clockwise, and where the mark itself lies; the same corners the panel's "Lay the plate" view and the per-plate report draw
(:func:`mppf.model.placement.placement_of`). On a real press the operator then confirms
that the plate lies there (:func:`mppf.cli.press_policy.confirm_motion`).
"""

from __future__ import annotations

from mppf.model.job import Job
from mppf.model.placement import placement_of


def placement_lines(job: Job) -> list[str]:
    """Plain lines telling the operator where to lay the cut plate of ``job`` (press mm).

    Parameters
    ----------
    job : Job
        A planned job; without a plate layout (an old job file) the lines say so.

    Returns
    -------
    list of str
        A heading, one line per corner of the plate as cut, and the mark.
    """
    layout = job.layout
    if layout is None or len(layout.outline_mm) < 3:
        return ["lay the plate: the job holds no plate outline (an old job file): place it as planned "
                "and check it against the plan's printout"]
    placement = placement_of(layout)
    margin = (f"with its {placement.margin_mm:g} mm trim margin" if placement.margin_mm > 0
              else "cut to its net outline")
    mark_x, mark_y = placement.mark_mm
    lines = [f"lay the plate as cut ({margin}) on the bed with its corners at (press mm, x along the columns, "
             f"y along the rows, origin at the bed centre):"]
    for row in placement.rows():
        note = "  <- the corner nearest the reference mark (the mark is on it)" if row["mark"] else ""
        lines.append(f"  corner {row['name']}: x {row['x_mm']:9.1f} mm, y {row['y_mm']:9.1f} mm{note}")
    lines.append(f"  reference mark: x {mark_x:9.1f} mm, y {mark_y:9.1f} mm (on corner A of the plate as cut, "
                 "as on the cutter's drawing)")
    return lines
