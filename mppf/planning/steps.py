"""Multi-step forming and the validation of planned strokes.

A punch's *travel* is its tip height minus its flat-plate height (lower tips 0, upper
tips t). Step k of N moves every active tip to ``k/N`` of its final travel, so the
strokes are monotonic and the last step is the target. One step must not change the
height difference between two neighbouring punches (same row or column, same matrix,
both active) by more than the press's dimpling limit ``max_neighbour_diff_mm``, so
N = ceil(largest neighbour difference of the final travel / limit). See
``docs/planning.md``.
"""

from __future__ import annotations

import math

import numpy as np

from mppf.core.errors import LimitError
from mppf.core.grid import largest_neighbour_difference, neighbour_differences
from mppf.core.validate import check_number
from mppf.planning.job import StepStrokes
from mppf.planning.press import PressConfig

GAP_TOLERANCE_MM = 0.01
"""The tip gap of a punch pair may be this much below the thickness (rounding)."""

LIMIT_TOLERANCE_MM = 1e-6
MAX_STEPS = 200
"""Most press steps one job may hold (a larger count is a typing error or a dimpling
limit far too small for the plate; the job file grows with every step)."""
MAX_LISTED = 10


def flat_heights(thickness_mm: float) -> tuple[float, float]:
    """(upper, lower) tip heights that hold the flat plate: (t, 0)."""
    return float(thickness_mm), 0.0


def steps_needed(upper_mm, lower_mm, active, press: PressConfig, thickness_mm: float) -> int:
    """Fewest steps that keep every step within the dimpling limit."""
    up0, lo0 = flat_heights(thickness_mm)
    worst = max(largest_neighbour_difference(upper_mm - up0, active),
                largest_neighbour_difference(lower_mm - lo0, active))
    return max(1, math.ceil(worst / press.max_neighbour_diff_mm - 1e-9))


def split_steps(upper_mm, lower_mm, active, thickness_mm: float, n_steps: int) -> list[StepStrokes]:
    """N steps from the flat plate to the final strokes, each a fraction k/N of the travel.

    Parameters
    ----------
    upper_mm, lower_mm : (rows, cols) float
        Final tip heights (NaN where inactive).
    active : (rows, cols) bool
    thickness_mm : float
    n_steps : int, >= 1

    Returns
    -------
    list of StepStrokes
    """
    n_steps = check_number("the number of steps", n_steps, low=1, integer=True)
    up0, lo0 = flat_heights(thickness_mm)
    steps = []
    for k in range(1, n_steps + 1):
        f = k / n_steps
        upper = np.where(active, up0 + f * (upper_mm - up0), np.nan)
        lower = np.where(active, lo0 + f * (lower_mm - lo0), np.nan)
        steps.append(StepStrokes(upper_mm=upper, lower_mm=lower, active=active.copy()))
    return steps


def _label(side: str, rc) -> str:
    return f"{side}[{rc[0]},{rc[1]}]"


def validate_steps(steps: list[StepStrokes], press: PressConfig, thickness_mm: float) -> dict:
    """Check every step before anything is written.

    Checks: active strokes inside the limits of their matrix; the tip gap (upper minus
    lower) of each active pair at least the thickness (within ``GAP_TOLERANCE_MM``);
    no step adds more than ``max_neighbour_diff_mm`` to the height difference of
    neighbouring punches; strokes monotonic from step to step.

    Returns
    -------
    dict
        ``passed`` and the measured figures: ``min_gap_mm``, ``max_neighbour_step_mm``,
        stroke ranges per matrix.

    Raises
    ------
    LimitError
        Listing the punches (side[row,col], step) and values that violate a check.
    """
    up0, lo0 = flat_heights(thickness_mm)
    problems: list[str] = []
    n_problems = 0
    min_gap = math.inf
    max_step_diff = 0.0
    prev_u = np.full(press.shape, up0)
    prev_l = np.full(press.shape, lo0)
    direction_u = direction_l = None
    for k, step in enumerate(steps, start=1):
        act = step.active
        for side, values, lim in (("upper", step.upper_mm, press.upper), ("lower", step.lower_mm, press.lower)):
            bad = act & ((values < lim.min_mm - LIMIT_TOLERANCE_MM) | (values > lim.max_mm + LIMIT_TOLERANCE_MM)
                         | ~np.isfinite(values))
            n_problems += int(bad.sum())
            problems += [f"step {k} {_label(side, rc)} stroke {values[tuple(rc)]:.2f} mm outside "
                         f"{lim.min_mm:g}..{lim.max_mm:g}" for rc in np.argwhere(bad)[:MAX_LISTED]]
        gap = np.where(act, step.upper_mm - step.lower_mm, np.inf)
        if act.any():
            min_gap = min(min_gap, float(gap[act].min()))
        bad = act & (gap < thickness_mm - GAP_TOLERANCE_MM)
        n_problems += int(bad.sum())
        problems += [f"step {k} pair[{r},{c}] tip gap {gap[r, c]:.2f} mm < thickness {thickness_mm:g} mm"
                     for r, c in np.argwhere(bad)[:MAX_LISTED]]
        for side, values, prev in (("upper", step.upper_mm, prev_u), ("lower", step.lower_mm, prev_l)):
            for diff, first, second in neighbour_differences(values - prev, act):
                if diff.size:
                    max_step_diff = max(max_step_diff, float(np.abs(diff).max()))
                bad = np.abs(diff) > press.max_neighbour_diff_mm + LIMIT_TOLERANCE_MM
                n_problems += int(bad.sum())
                problems += [
                    f"step {k} {_label(side, a)}-{_label(side, b)} height difference changes by "
                    f"{d:+.2f} mm (dimpling limit {press.max_neighbour_diff_mm:g})"
                    for d, a, b in zip(diff[bad][:MAX_LISTED], first[bad], second[bad])
                ]
        move_u = np.where(act, step.upper_mm - prev_u, 0.0)
        move_l = np.where(act, step.lower_mm - prev_l, 0.0)
        if direction_u is not None:
            back = act & ((move_u * direction_u < -LIMIT_TOLERANCE_MM) | (move_l * direction_l < -LIMIT_TOLERANCE_MM))
            n_problems += int(back.sum())
            problems += [f"step {k} pair[{r},{c}] reverses direction" for r, c in np.argwhere(back)[:MAX_LISTED]]
        direction_u = np.where(np.abs(move_u) > LIMIT_TOLERANCE_MM, np.sign(move_u),
                               0.0 if direction_u is None else direction_u)
        direction_l = np.where(np.abs(move_l) > LIMIT_TOLERANCE_MM, np.sign(move_l),
                               0.0 if direction_l is None else direction_l)
        prev_u = np.where(act, step.upper_mm, prev_u)
        prev_l = np.where(act, step.lower_mm, prev_l)
    if problems:
        shown = problems[:MAX_LISTED]
        more = f"; and {n_problems - len(shown)} more" if n_problems > len(shown) else ""
        raise LimitError(
            f"the planned strokes fail validation ({n_problems} problem(s)): " + "; ".join(shown) + more,
            hint="give more steps (--steps), a press with longer strokes, or check the plate and thickness",
        )
    final = steps[-1]
    act = final.active

    def value_range(values):
        return [float(np.min(values[act])), float(np.max(values[act]))] if act.any() else None

    return {
        "passed": True,
        "n_steps": len(steps),
        "min_gap_mm": None if not math.isfinite(min_gap) else min_gap,
        "max_neighbour_step_mm": max_step_diff,
        "dimpling_limit_mm": press.max_neighbour_diff_mm,
        "upper_range_mm": value_range(final.upper_mm),
        "lower_range_mm": value_range(final.lower_mm),
        "upper_limits_mm": [press.upper.min_mm, press.upper.max_mm],
        "lower_limits_mm": [press.lower.min_mm, press.lower.max_mm],
    }
