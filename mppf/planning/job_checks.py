"""The plan re-derived: what a job says twice must agree, before anything is pressed.

A job holds several values the planner derived from one another: the plate as cut is the net
outline grown by the trim margin; a section's flat transform is the plate's one transform
shifted by the section's plate centre; its marks in plate coordinates are its marks in the flat
file carried by that transform; its marks on the bed lie over the axes of its mark punches,
which are the punches chosen from the section's active punches under the net plate; the job's
own steps, transforms and layout are section 1's; its punch axes are its press's; the split's
sections are all there, once
each; the counts of steps and sections match the planner's reports; the planner's validation
passed. :func:`check_plan` recomputes each of them and refuses a job where one differs by
more than :data:`PLACEMENT_TOLERANCE_MM` (a hand edit, a broken tool, a planner bug): the seal
(:mod:`mppf.core.seal`) says *that* a job changed, these checks say *what is inconsistent*, even
in a job sealed by someone who had the key. Called by :func:`mppf.planning.validate.validate_job`.
"""

from __future__ import annotations

import numpy as np

from mppf.core.errors import ConfigError
from mppf.core.polygon import contains, offset_convex
from mppf.core.transform import apply_tf, make_tf
from mppf.model.job_provenance import SectionalSummary

PLACEMENT_TOLERANCE_MM = 0.01
"""Largest difference between a stored placement (mm) and the one re-derived from the plan."""
ROTATION_TOLERANCE = 1e-6
HINT = "re-plan the plate with 'mppf plan' (a job is never edited by hand)"


def check_plan(job) -> None:
    """Refuse a job whose placements, marks, sections or step counts do not follow from its plan.

    Parameters
    ----------
    job : mppf.model.job.Job

    Raises
    ------
    ConfigError
        Listing every inconsistency: where (section, step), the stored and the re-derived value.
    """
    problems: list[str] = []
    for name, axis in (("punch_x_mm", job.press.punch_x_mm), ("punch_y_mm", job.press.punch_y_mm)):
        off = float(np.abs(np.asarray(getattr(job, name), dtype=float) - axis).max())
        if off > PLACEMENT_TOLERANCE_MM:
            problems.append(f"{name} is {off:.2f} mm away from the punch axes of its press (pitch and matrix)")
    # a job the loop corrected keeps the planner's reports of its first cycle: their step counts are not its own
    counted = job.loop is None
    problems += _check_piece("", job.steps, job.layout, job.reports, job.press, counted)
    if job.sections is not None:
        problems += _check_sections(job, counted)
    if problems:
        shown = "; ".join(problems[:10]) + (f"; and {len(problems) - 10} more" if len(problems) > 10 else "")
        raise ConfigError(f"the job does not follow from its own plan ({len(problems)} problem(s)): {shown}; "
                          "nothing was sent to the press", hint=HINT)


def _check_piece(where: str, steps, layout, reports, press, counted: bool = True) -> list[str]:
    """The checks of one piece (the job or a section, ``reports`` its
    :class:`~mppf.model.job_reports.PlanReports`): validation, step count, repeated steps, the outline."""
    out = []
    validation = reports.validation
    if validation is not None and validation.passed is not True:
        out.append(f"{where}the planner's validation did not pass (validation.passed is {validation.passed!r})")
    counts = [("n_steps", reports.n_steps),
              ("validation.n_steps", None if validation is None else validation.n_steps)]
    counts = counts if counted else []
    for name, value in counts:
        if value is not None and value != len(steps):
            out.append(f"{where}{name} is {value!r} but the job holds {len(steps)} step(s) (a step was added or "
                       "removed)")
    for k in range(1, len(steps)):
        a, b = steps[k - 1], steps[k]
        if np.array_equal(a.active, b.active) and np.allclose(a.upper_mm, b.upper_mm, equal_nan=True, atol=0.0) \
                and np.allclose(a.lower_mm, b.lower_mm, equal_nan=True, atol=0.0):
            out.append(f"{where}step {k + 1} repeats step {k} (the same strokes pressed twice)")
    if layout is not None and len(layout.net_outline_mm) >= 3:
        try:
            grown = offset_convex(layout.net_outline_mm, layout.margin_mm)
        except Exception:  # noqa: BLE001 - a degenerate outline is reported like a wrong one
            grown = None
        if grown is None:
            out.append(f"{where}the net outline cannot be grown by the {layout.margin_mm:g} mm trim margin")
        else:
            off = _polygon_distance(grown, layout.outline_mm)
            if off > PLACEMENT_TOLERANCE_MM:
                out.append(f"{where}the plate outline as cut is {off:.2f} mm away from the net outline grown by "
                           f"the {layout.margin_mm:g} mm trim margin")
    return out


def _polygon_distance(a, b) -> float:
    """Largest distance (mm) of a corner of either closed polygon from the other's outline (0: the same outline,
    whatever the first corner or the corners on an edge)."""
    def to_outline(points, polygon):
        start, end = polygon, np.roll(polygon, -1, axis=0)
        edge = end - start
        length2 = np.maximum((edge ** 2).sum(axis=1), 1e-30)
        t = np.clip(((points[:, None, :] - start[None]) * edge[None]).sum(axis=2) / length2[None], 0.0, 1.0)
        nearest = start[None] + t[..., None] * edge[None]
        return np.sqrt(((points[:, None, :] - nearest) ** 2).sum(axis=2)).min(axis=1)

    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    with np.errstate(all="ignore"):  # absurd coordinates (1e300 mm) give inf or nan: not the same outline
        off = float(max(to_outline(a, b).max(), to_outline(b, a).max()))
    return off if np.isfinite(off) else np.inf


def _check_sections(job, counted: bool = True) -> list[str]:
    """The sectional checks: the split complete, section 1 the job's own, each section's placement and marks."""
    sections, press = job.sections, job.press
    out = _check_split(sections, job.sectional or SectionalSummary(), counted)
    first = sections[0]
    if len(first.steps) != len(job.steps) or any(
            not np.allclose(a.upper_mm, b.upper_mm, equal_nan=True) or not np.allclose(a.lower_mm, b.lower_mm,
                                                                                      equal_nan=True)
            for a, b in zip(first.steps, job.steps)):
        out.append("the job's own steps are not those of section 1")
    for name in ("tf_press_flat", "tf_press_design"):
        if not np.allclose(getattr(job, name), getattr(first, name), atol=PLACEMENT_TOLERANCE_MM, rtol=0.0):
            out.append(f"the job's {name} is not that of section 1")
    if job.layout is not None and (job.layout.outline_mm.shape != first.layout.outline_mm.shape or not np.allclose(
            job.layout.outline_mm, first.layout.outline_mm, atol=PLACEMENT_TOLERANCE_MM, rtol=0.0)):
        out.append("the job's plate outline is not that of section 1")
    base = make_tf(translation=[-first.plate_centre_mm[0], -first.plate_centre_mm[1], 0.0]) @ first.tf_press_flat
    for s in sections:
        out += _check_piece(f"section {s.index} ", s.steps, s.layout, s.reports, press, counted)
        out += _check_section_placement(s, base, press)
    return out


def _check_split(sections, info: SectionalSummary, counted: bool = True) -> list[str]:
    """Every section of the split there once: counts, cells, the planner's step total (``counted``)."""
    out = []
    n = info.n_sections
    if n is not None and n != len(sections):
        out.append(f"the plan has {n} section(s), the job holds {len(sections)} (a section was added or removed)")
    cells = [tuple(s.cell) for s in sections]
    repeated = sorted({c for c in cells if cells.count(c) > 1})
    if repeated:
        out.append(f"section cell(s) {repeated} appear more than once")
    counts = info.counts
    if counts is not None and len(counts) == 2:
        grid = {(a, b) for a in range(counts[0]) for b in range(counts[1])}
        missing, foreign = sorted(grid - set(cells)), sorted(set(cells) - grid)
        if missing:
            out.append(f"the split's cell(s) {missing} have no section (a section was removed)")
        if foreign:
            out.append(f"section cell(s) {foreign} are outside the {counts[0]} x {counts[1]} split")
    total = info.n_steps_total
    if counted and total is not None and total != sum(len(s.steps) for s in sections):
        out.append(f"the plan has {total} step(s) in all, the sections hold {sum(len(s.steps) for s in sections)}")
    return out


def _check_section_placement(s, base, press) -> list[str]:
    """One section's flat transform, marks and mark punches against the plan's one placement of the plate."""
    where, out = f"section {s.index} ", []
    shift = make_tf(translation=[-s.plate_centre_mm[0], -s.plate_centre_mm[1], 0.0]) @ s.tf_press_flat
    moved = float(np.abs(shift[:3, 3] - base[:3, 3]).max())
    if moved > PLACEMENT_TOLERANCE_MM or not np.allclose(shift[:3, :3], base[:3, :3], atol=ROTATION_TOLERANCE):
        out.append(f"{where}plate centre {_xy(s.plate_centre_mm)} and flat transform do not place the plate as "
                   f"section 1 does ({moved:.2f} mm apart)")
    plate = apply_tf(s.tf_press_flat, s.marks_flat_mm)[:, :2] - s.plate_centre_mm
    off = float(np.abs(plate - s.marks_plate_mm).max())
    if off > PLACEMENT_TOLERANCE_MM:
        out.append(f"{where}marks in plate coordinates {_xy(s.marks_plate_mm[0])}, {_xy(s.marks_plate_mm[1])} are "
                   f"{off:.2f} mm from the marks of the flat so placed")
    punches = np.asarray(s.mark_punches)
    if punches.shape != (2, 2) or np.any(punches < 0) or np.any(punches >= np.array(press.shape)):
        return out + [(f"{where}mark punches {punches.tolist()} are not punches of the {press.rows} x "
                       f"{press.cols} press")]
    axes = np.column_stack([press.punch_x_mm[punches[:, 1]], press.punch_y_mm[punches[:, 0]]])
    off = float(np.abs(axes - s.marks_press_mm).max())
    if off > PLACEMENT_TOLERANCE_MM:
        out.append(f"{where}marks on the bed {_xy(s.marks_press_mm[0])}, {_xy(s.marks_press_mm[1])} are {off:.2f} "
                   f"mm from the axes of their punches {_xy(axes[0])}, {_xy(axes[1])}")
    expected = _mark_punches(s, press)
    if expected is not None and not np.array_equal(expected, punches):
        out.append(f"{where}mark punches {(punches + press.label_base).tolist()} (row, col) are not the ones the "
                   f"plan chooses, {(expected + press.label_base).tolist()}")
    return out


def _mark_punches(section, press):
    """The mark punches the planner chooses for the section (None when none can be chosen)."""
    from mppf.planning.sections import mark_punches

    gx, gy = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    under = contains(section.layout.net_outline_mm, np.column_stack([gx.ravel(), gy.ravel()])).reshape(press.shape)
    try:
        return mark_punches(np.asarray(section.steps[-1].active, bool) & under)
    except Exception:  # noqa: BLE001 - no two punches under the plate: reported by the other checks
        return None


def _xy(values) -> str:
    x, y = np.asarray(values, dtype=float)[:2]
    return f"({x:.1f}, {y:.1f}) mm"
