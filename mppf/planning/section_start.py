"""Where a later section's steps start: the plate as the sections before it formed it.

A section pressed after others meets formed plate (its overlap with them). Its steps do not start
from the flat plate's tip heights: from flat, its first steps would bend the formed overlap back
part of the way before its last step bends it again. They start from the **formed plate as the
planner predicts it**, in the section's own pose:

- over the punches an earlier section pressed (:func:`formed_punches`), the design's own mid heights
  in this section's pose (``layout.design_mid_mm``: after springback the plate is the design);
- over the rest, the formed part continued as the smoothest surface on the punch grid
  (:func:`continue_heights`: least squared second differences along rows and columns, the formed
  punches held), which continues a formed strip attached along a straight border by its tangent
  plane, as an unformed plate leaves the last punch of the section before;
- each pair's tips that far apart as in the section's final step (the tips touch the plate), held to
  the stroke limits.

Steps k/N of the way from there to the final strokes (:func:`steps_from`, N the fewest within the
dimpling limit measured from the start) move every punch one way: over the formed overlap from the
design to the section's strokes (the over-bent target with springback: the loading side), so the
formed part is never bent back. The PLC takes a step that is lawful from the flat plate or from where
its punches stand; between sections they stand where the section before left them, so the first step
must also be lawful from flat: where the formed plate is too steep for that, the start is a share of
the way from flat to it (:func:`plan_section_steps`), stored as the section's
``transition.start_share``. The start follows from the job alone (:func:`section_start`), so the one
job validator (:func:`mppf.planning.validate.validate_job`) derives the same start and checks the
steps from it. Sections without a share (the first, and jobs planned before) start from flat. See
``docs/sections.md``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.linalg import lsqr

from mppf.core.grid import largest_neighbour_difference
from mppf.model.job_parts import StepStrokes
from mppf.model.press import PressConfig
from mppf.planning.sections import index_offset, shifted
from mppf.planning.steps import MAX_STEPS, flat_heights


def formed_punches(press: PressConfig, centre_mm, active, earlier) -> np.ndarray:
    """(rows, cols) bool: this section's active punches over plate that an earlier section pressed.

    Parameters
    ----------
    press : PressConfig
    centre_mm : (2,) float
        Plate x, y under the bed's centre in this section, mm.
    active : (rows, cols) bool
        This section's active punches.
    earlier : iterable of ((2,) float, (rows, cols) bool)
        Each earlier section's bed centre (plate x, y, mm) and active punches.
    """
    formed = np.zeros(press.shape, dtype=bool)
    for centre, act in earlier:
        formed |= shifted(np.asarray(act, dtype=bool), index_offset(press, centre_mm, centre), False)
    return formed & np.asarray(active, dtype=bool)


def continue_heights(values, known, active) -> np.ndarray:
    """(rows, cols) mm: ``values`` at ``known``, continued over ``active & ~known`` as the smoothest surface.

    Least squared second differences along rows and columns (every run of three neighbouring active
    punches with one unknown or more), the known punches held: a linear continuation beyond a straight
    border. NaN outside ``active``; an unknown punch with no such run keeps the mean of the known ones.
    """
    values = np.asarray(values, dtype=float)
    known = np.asarray(known, dtype=bool) & np.isfinite(values)
    active = np.asarray(active, dtype=bool)
    out = np.where(known, values, np.nan)
    unknown = active & ~known
    if not unknown.any() or not known.any():
        return np.where(active, out, np.nan)
    index = np.full(values.shape, -1)
    index[unknown] = np.arange(int(unknown.sum()))
    rows, cols, data, rhs = [], [], [], []
    for axis in (0, 1):
        n = values.shape[axis] - 2
        if n < 1:
            continue
        runs = [np.arange(j, j + n) for j in range(3)]  # the first, middle and last punch of each run of three
        ok = np.all([np.take(active, r, axis=axis) for r in runs], axis=0)
        ok &= np.any([np.take(unknown, r, axis=axis) for r in runs], axis=0)
        eq = np.cumsum(ok).reshape(ok.shape) - 1 + len(rhs)
        b = np.zeros(int(ok.sum()))
        for r, w in zip(runs, (1.0, -2.0, 1.0)):
            idx, val = np.take(index, r, axis=axis)[ok], np.take(np.where(known, values, 0.0), r, axis=axis)[ok]
            free = idx >= 0
            rows.append(eq[ok][free])
            cols.append(idx[free])
            data.append(np.full(int(free.sum()), w))
            b -= np.where(free, 0.0, w * val)
        rhs.extend(b.tolist())
    if not rhs:
        out[unknown] = float(values[known].mean())
        return np.where(active, out, np.nan)
    matrix = coo_matrix((np.concatenate(data), (np.concatenate(rows), np.concatenate(cols))),
                        shape=(len(rhs), int(unknown.sum()))).tocsr()
    solved = lsqr(matrix, np.asarray(rhs), atol=1e-12, btol=1e-12, iter_lim=20 * matrix.shape[1] + 100)[0]
    touched = np.zeros(matrix.shape[1], dtype=bool)
    touched[np.unique(matrix.indices)] = True
    out[unknown] = np.where(touched, solved, float(values[known].mean()))
    return np.where(active, out, np.nan)


def start_tips(press: PressConfig, design_mid_mm, formed, final: StepStrokes):
    """(upper, lower) (rows, cols) mm: the tips touching the formed plate as predicted (NaN where inactive).

    The design's mid heights over the formed punches, continued over the rest (:func:`continue_heights`),
    each pair's tips as far apart as in ``final`` (the section's last step), in the pose where this plate
    rests on the lower punches at their flat height (:func:`rest_plane`), held to the stroke limits.
    """
    active = np.asarray(final.active, dtype=bool)
    mid = continue_heights(design_mid_mm, formed, active)
    half = 0.5 * (final.upper_mm - final.lower_mm)
    mid = mid + rest_plane(press, mid - half, active)
    lower = np.clip(mid - half, press.lower.min_mm, press.lower.max_mm)
    upper = np.clip(np.maximum(mid + half, lower + (final.upper_mm - final.lower_mm)),
                    press.upper.min_mm, press.upper.max_mm)
    return np.where(active, upper, np.nan), np.where(active, lower, np.nan)


def rest_plane(press: PressConfig, lower_mm, active) -> np.ndarray:
    """(rows, cols) mm: the rigid move (a plane) that lays a plate with these lower tip heights on the bed.

    The plate's underside over the active punches (``lower_mm``: where their tips would touch it) is moved
    rigidly (small tilts: a plane) to rest on the lower tips at their flat height (0) under gravity: the
    lowest height of its centre of mass (taken as the mean of the active punch positions: the part the bed
    carries) with no tip above the plate; a linear programme. The part beyond the bed is taken as carried at
    whatever height the rest gives it (roller table, crane).
    """
    from scipy.optimize import linprog

    gx, gy = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    use = np.asarray(active, dtype=bool) & np.isfinite(lower_mm)
    if use.sum() < 3:
        return np.zeros(press.shape)
    rows = np.column_stack([np.ones(int(use.sum())), gx[use], gy[use]])
    scale = np.array([1.0, 1e-3, 1e-3])  # tilts in mm per m: a well-scaled programme
    result = linprog(rows.mean(axis=0) * scale, A_ub=-rows * scale, b_ub=np.asarray(lower_mm)[use],
                     bounds=[(None, None)] * 3, method="highs")
    if result.status != 0:  # the punches on a line (no tilt across them is fixed): rest on the lowest one
        return np.full(press.shape, -float(np.min(np.asarray(lower_mm)[use])))
    a, b, c = result.x * scale
    return a + b * gx + c * gy


def section_start(sections, position: int, press: PressConfig, thickness_mm: float):
    """The start of the steps of the section at ``position`` (0-based, pressing order), or None: from flat.

    From the job alone: the earlier sections' bed centres and active punches (their last steps), this
    section's design mid heights, last step and ``transition.start_share`` (:func:`shared_start`). None for a
    section without a share (the first, and jobs planned before), without design heights, or over no formed
    punch.

    Returns
    -------
    (upper, lower) : (rows, cols) float, mm, or None
    """
    s = sections[position]
    share = None if s.transition is None else s.transition.start_share
    if share is None or s.layout is None or s.layout.design_mid_mm is None:
        return None
    final = s.steps[-1]
    earlier = [(-np.asarray(e.plate_centre_mm, dtype=float), e.steps[-1].active) for e in sections[:position]]
    formed = formed_punches(press, -np.asarray(s.plate_centre_mm, dtype=float), final.active, earlier)
    if not formed.any():
        return None
    return shared_start(start_tips(press, s.layout.design_mid_mm, formed, final), share, final.active, thickness_mm)


def shared_start(tips, share: float, active, thickness_mm: float):
    """(upper, lower) (rows, cols) mm: ``share`` of the way from the flat plate's tips to ``tips`` (NaN inactive)."""
    flat_up, flat_lo = flat_heights(thickness_mm)
    return (np.where(active, flat_up + share * (tips[0] - flat_up), np.nan),
            np.where(active, flat_lo + share * (tips[1] - flat_lo), np.nan))


def steps_needed_from(start, final_up, final_lo, active, press: PressConfig, thickness_mm: float) -> int:
    """Fewest steps from ``start`` ((upper, lower) or None: flat) within the dimpling limit."""
    up0, lo0 = start if start is not None else flat_heights(thickness_mm)
    worst = max(largest_neighbour_difference(final_up - up0, active), largest_neighbour_difference(final_lo - lo0,
                                                                                                   active))
    return max(1, math.ceil(worst / press.max_neighbour_diff_mm - 1e-9))


def steps_from(start, final_up, final_lo, active, thickness_mm: float, n_steps: int) -> list[StepStrokes]:
    """N steps from ``start`` ((upper, lower) (rows, cols) mm, or None: the flat plate) to the final strokes.

    Step k moves every active tip ``k/N`` of the way; NaN at inactive punches.

    Raises
    ------
    LimitError
        More than :data:`mppf.planning.steps.MAX_STEPS` steps.
    """
    from mppf.core.errors import LimitError

    if n_steps > MAX_STEPS:
        raise LimitError(f"the section needs {n_steps} press steps to keep within the dimpling limit, more than the "
                         f"{MAX_STEPS} one job may hold", hint="check [forming] max_neighbour_diff_mm in the press "
                         "description")
    active = np.asarray(active, dtype=bool)
    up0, lo0 = start if start is not None else flat_heights(thickness_mm)
    out = []
    for k in range(1, int(n_steps) + 1):
        f = k / n_steps
        out.append(StepStrokes(upper_mm=np.where(active, up0 + f * (final_up - up0), np.nan),
                               lower_mm=np.where(active, lo0 + f * (final_lo - lo0), np.nan), active=active.copy()))
    return out


START_SHARES = tuple(np.round(np.linspace(1.0, 0.1, 10), 2))
"""The shares of the way to the formed plate tried for a later section's start, largest first."""

EXTRA_STEPS = 4
"""Most steps a later section may take beyond the fewest its dimpling limit needs, to start on the formed plate."""

LAWFUL_FROM_FLAT = 2
"""A later section's first steps that must also be lawful from the flat plate: the first, and the second, which
follows a first step cut short while the punches still stood about where the section before left them."""


def plan_section_steps(press: PressConfig, thickness_mm: float, design_mid_mm, final: StepStrokes, formed,
                       n_steps: int | None = None):
    """The start, the steps and the start's share of a section: from the formed plate where it can, else from flat.

    The start is the largest share (:data:`START_SHARES`) of the way from the flat plate's tips to the tips
    touching the formed plate (:func:`start_tips`, :func:`shared_start`) whose first steps
    (:data:`LAWFUL_FROM_FLAT`), with the fewest steps within the dimpling limit from the start (up to
    :data:`EXTRA_STEPS` more), are also lawful steps from the flat plate (no neighbour difference of their
    strokes beyond the dimpling limit): the PLC takes a step that is lawful from the flat plate or from where
    its punches stand, and between sections they do not stand where the plate lies. With no such share (or no
    formed punch) the steps go from flat.

    Parameters
    ----------
    press : PressConfig
    thickness_mm : float
    design_mid_mm : (rows, cols) float or None
        The design's mid heights in the section's pose, mm (None: from flat).
    final : StepStrokes
        The section's final strokes.
    formed : (rows, cols) bool
        Its punches over plate an earlier section pressed (:func:`formed_punches`).
    n_steps : int, optional
        The number of steps; default the fewest within the dimpling limit from the start.

    Returns
    -------
    start : (upper, lower) of (rows, cols) float, mm, or None (flat)
    steps : list of StepStrokes
    share : float or None
        The start's share (None: flat).
    """
    formed, active, limit = np.asarray(formed, dtype=bool), final.active, press.max_neighbour_diff_mm
    if design_mid_mm is not None and formed.any():
        tips = start_tips(press, design_mid_mm, formed, final)
        for share in START_SHARES:
            start = shared_start(tips, float(share), active, thickness_mm)
            least = steps_needed_from(start, final.upper_mm, final.lower_mm, active, press, thickness_mm)
            for n in ([n_steps] if n_steps is not None else range(least, least + EXTRA_STEPS + 1)):
                if n < least:
                    continue
                steps = steps_from(start, final.upper_mm, final.lower_mm, active, thickness_mm, n)
                if all(max(largest_neighbour_difference(step.upper_mm, active),
                           largest_neighbour_difference(step.lower_mm, active)) <= limit + 1e-9
                       for step in steps[:LAWFUL_FROM_FLAT]):
                    return start, steps, float(share)
    n = n_steps if n_steps is not None else steps_needed_from(None, final.upper_mm, final.lower_mm, active, press,
                                                              thickness_mm)
    return None, steps_from(None, final.upper_mm, final.lower_mm, active, thickness_mm, n), None

