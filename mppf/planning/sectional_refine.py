"""Each section's strokes refined on the plate model, as a single piece's are (``docs/sections.md``, item 4).

A single piece's springback strokes are the exact contact of the over-bent design, then refined by
virtual press cycles on the plate model against the design's mid heights at the punches
(:func:`mppf.correct.virtual_cycles.refine_strokes`, :func:`mppf.planning.plan.plan_job` step 5). A
section gets the same: its strokes (the contact of the whole plate's over-bent target in the section's
pose), its design mid heights at its active punches (the target), the planned material, and the part
of the plate that lies over the bed (:func:`section_outline`: the plate as cut, clipped to the bed and
the trim reach). The refinement's change of the strokes is the section's own correction, blended in the
transition zones with the earlier sections' as planned (:func:`mppf.planning.sectional._blend`), so where
sections meet they press the same change and the border rules hold.
"""

from __future__ import annotations

import numpy as np

from mppf.correct.virtual_cycles import refine_strokes
from mppf.model.job_parts import StepStrokes
from mppf.model.material import Material
from mppf.model.press import PressConfig


def section_outline(press: PressConfig, outline_mm, reach_mm: float) -> np.ndarray:
    """The plate as cut, clipped to the bed grown by ``reach_mm``: the part the section's refinement models.

    Parameters
    ----------
    press : PressConfig
    outline_mm : (k, 2) float
        The plate's outline as cut in the section's pose (press x, y), mm; convex.
    reach_mm : float
        How far beyond the outermost punch axes the modelled plate reaches, mm (>= 0).

    Returns
    -------
    (m, 2) float
        The clipped convex outline, mm (the outline itself when it lies on the bed).
    """
    half = np.asarray(press.bed_size_mm, dtype=float) / 2.0 + float(reach_mm)
    poly = [np.asarray(p, dtype=float) for p in np.asarray(outline_mm, dtype=float)]
    for axis in (0, 1):
        for sign in (1.0, -1.0):
            poly = _clip(poly, axis, sign, float(half[axis]))
            if len(poly) < 3:
                return np.asarray(outline_mm, dtype=float)
    return np.array(poly)


def _clip(poly, axis: int, sign: float, limit: float) -> list:
    """Sutherland-Hodgman: the polygon's part where ``sign * p[axis] <= limit``."""
    out = []
    for k, cur in enumerate(poly):
        prev = poly[k - 1]
        inside_cur, inside_prev = sign * cur[axis] <= limit, sign * prev[axis] <= limit
        if inside_cur != inside_prev:
            s = (sign * limit - prev[axis]) / (cur[axis] - prev[axis])
            out.append(prev + s * (cur - prev))
        if inside_cur:
            out.append(cur)
    return out


def refine_section(press: PressConfig, contact: StepStrokes, target_mid_mm, outline_mm, thickness_mm: float,
                   material: Material):
    """The section's correction of its contact strokes by virtual press cycles on the plate model.

    Parameters
    ----------
    press : PressConfig
    contact : StepStrokes
        The section's contact strokes (rows, cols) mm, NaN where inactive, and its active punches.
    target_mid_mm : (rows, cols) float
        The design's mid heights at the section's active punches in its pose, mm.
    outline_mm : (k, 2) float
        The part of the plate the model holds (:func:`section_outline`), mm.
    thickness_mm : float
    material : Material
        The planned material (the weakest of the declared range).

    Returns
    -------
    d_upper, d_lower : (rows, cols) float
        Refined minus contact strokes, mm (0 where inactive).
    report : dict
        ``virtual_cycles``, ``predicted_max_mm``, ``history_mm`` (as a single piece's refinement).
    """
    refined = refine_strokes(press, contact, target_mid_mm, outline_mm, thickness_mm, material)
    act = np.asarray(contact.active, dtype=bool)
    d_up = np.where(act, refined.upper_mm - contact.upper_mm, 0.0)
    d_lo = np.where(act, refined.lower_mm - contact.lower_mm, 0.0)
    report = {"virtual_cycles": len(refined.history_mm) - 1, "predicted_max_mm": float(refined.predicted_max_mm),
              "history_mm": [float(h) for h in refined.history_mm]}
    return d_up, d_lo, report


def refinement_summary(reports: list[dict]) -> dict:
    """The job's refinement report from the sections' (:func:`refine_section`): the virtual cycles of all
    sections, the largest predicted deviation left, and per cycle the largest over the sections (mm)."""
    longest = max(len(r["history_mm"]) for r in reports)
    padded = [r["history_mm"] + [r["history_mm"][-1]] * (longest - len(r["history_mm"])) for r in reports]
    return {"virtual_cycles": int(sum(r["virtual_cycles"] for r in reports)),
            "predicted_max_mm": float(max(r["predicted_max_mm"] for r in reports)),
            "history_mm": [float(v) for v in np.max(np.array(padded), axis=0)]}


def section_refinement(index: int, contact: StepStrokes, target, outline, ctx: dict):
    """The section's own correction of its contact strokes (``ctx``: the sectional planner's context).

    With ``ctx["refine"]`` (springback), :func:`refine_section` over the section's part of the plate
    (:func:`section_outline`); else none (zeros, and None for the report).
    """
    press = ctx["press"]
    if not ctx["refine"]:
        return np.zeros(press.shape), np.zeros(press.shape), None
    ctx["reporter"].info(f"section {index} of {ctx['n']}: refining the springback strokes on the plate model")
    # the part over the bed and one transition zone beyond (plate there is shared with the neighbours: held on,
    # not a free edge), plus the trim reach
    reach = ctx["zone"] + ctx["margin"] + press.trim_allowance_mm
    model_outline = section_outline(press, outline, reach)
    return refine_section(press, contact, target, model_outline, ctx["t"], ctx["planned_material"])
