"""Multi-step forming: the press steps from the flat plate to the final strokes.

A punch's *travel* is its tip height minus its flat-plate height (lower tips 0, upper
tips t). Step k of N moves every active tip to ``k/N`` of its final travel, so the
strokes are monotonic and the last step is the target. One step must not change the
height difference between two neighbouring punches (same row or column, same matrix,
both active) by more than the press's dimpling limit ``max_neighbour_diff_mm``, so
N = ceil(largest neighbour difference of the final travel / limit). See
``docs/planning.md``. The steps are checked by the one job validator,
:func:`mppf.planning.validate.validate_steps`.
"""

from __future__ import annotations

import math

import numpy as np

from mppf.core.grid import largest_neighbour_difference
from mppf.core.validate import check_number
from mppf.model.job_parts import StepStrokes
from mppf.model.press import PressConfig

MAX_STEPS = 200
"""Most press steps one job may hold (a larger count is a typing error or a dimpling
limit far too small for the plate; the job file grows with every step)."""


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
