"""Springback pre-compensation by virtual press cycles on the plate model.

Before anything is pressed, :func:`refine_strokes` runs the shop's own correction loop on the
plate model (:mod:`mppf.forming.precompensate`) with the NOMINAL material: predict the
sprung-back plate from the strokes, measure its deviation from the design at every punch,
correct the strokes (:func:`mppf.correct.compensate.compensate`, the springback-model step), and
repeat until the predicted deviation is below ``tolerance_mm``. This is the simulation-based
displacement adjustment of die design, done per plate, before the first press; the planner
(:func:`mppf.planning.plan.plan_job`) runs it. The model is its own truth here, so the step has
no trust region; the loop's correction of a pressed plate is :func:`mppf.correct.step.correct_step`.

What it cannot know is the plate's true yield stress and thickness (they scatter around
the nominal values); the real bend - measure - compare loop corrects that.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mppf.core.validate import check_number
from mppf.correct.compensate import CompensateOptions, compensate
from mppf.forming.precompensate import deviation, predict_mid_heights
from mppf.model.job_parts import StepStrokes
from mppf.model.material import Material
from mppf.model.press import PressConfig

ITERATIONS = 10
"""Most virtual cycles."""

TOLERANCE_MM = 0.1
"""Virtual cycles stop when the predicted largest deviation at the punches is below this."""


@dataclass(frozen=True, eq=False)
class Refinement:
    """Strokes refined on the plate model.

    Attributes
    ----------
    upper_mm, lower_mm : (rows, cols) float
        Refined tip heights (NaN where inactive).
    predicted_max_mm : float
        Predicted largest deviation at the punches of the returned strokes, mm.
    history_mm : list of float
        Predicted largest deviation at the punches of each virtual cycle's strokes, mm.
    notes : list of str
    """

    upper_mm: np.ndarray
    lower_mm: np.ndarray
    predicted_max_mm: float
    history_mm: list[float] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def refine_strokes(press: PressConfig, start: StepStrokes, target_mid_mm, outline_xy_mm, thickness_mm: float,
                   material: Material, *, iterations: int = ITERATIONS,
                   tolerance_mm: float = TOLERANCE_MM) -> Refinement:
    """Correct strokes on the plate model until the predicted plate matches the design.

    Parameters
    ----------
    press : PressConfig
    start : StepStrokes
        Starting tip heights of both matrices (e.g. the over-bent plan; mm, NaN where inactive) and the
        active punches.
    target_mid_mm : (rows, cols) float
        The design's mid-surface height at each active punch axis (press z), in the
        same pose as the strokes.
    outline_xy_mm : (k, 2) float
        The plate's outline on the press (with its trim margin, if any).
    thickness_mm : float
    material : Material
        The NOMINAL material.
    iterations : int
        Most virtual cycles (>= 0).
    tolerance_mm : float
        Stop when the predicted largest deviation at the punches is below this.

    Returns
    -------
    Refinement
        The best strokes seen (the smallest predicted largest deviation).

    Raises
    ------
    InputError
        A negative iteration count or a non-positive tolerance.
    """
    iterations = check_number("the refinement's iterations", iterations, low=0, integer=True)
    tolerance_mm = check_number("the refinement's tolerance", tolerance_mm, low=0.0, low_open=True, unit="mm")
    act = np.asarray(start.active, dtype=bool)
    upper = np.where(act, np.asarray(start.upper_mm, dtype=float), np.nan)
    lower = np.where(act, np.asarray(start.lower_mm, dtype=float), np.nan)
    target = np.asarray(target_mid_mm, dtype=float)
    best = (np.inf, upper, lower)
    history: list[float] = []
    notes: list[str] = []
    for _ in range(iterations + 1):
        predicted = predict_mid_heights(press, upper, lower, act, outline_xy_mm, thickness_mm, material)
        # the deviation up to a rigid placement: the comparison of a scan removes its best plane
        error = deviation(press, predicted, target, act)
        worst = float(np.max(np.abs(error[act])))
        history.append(worst)
        if worst < best[0]:
            best = (worst, upper, lower)
        if worst < tolerance_mm or len(history) > iterations:
            break
        step = compensate(upper, lower, error, press=press, thickness_mm=thickness_mm, material=material,
                          options=CompensateOptions(max_step_ratio=None))
        upper, lower = np.where(act, step.upper_mm, np.nan), np.where(act, step.lower_mm, np.nan)
    notes.append(f"{len(history) - 1} virtual cycle(s) on the plate model (nominal material): predicted "
                 f"largest deviation at the punches {history[0]:.2f} -> {best[0]:.2f} mm")
    return Refinement(upper_mm=best[1], lower_mm=best[2], predicted_max_mm=best[0], history_mm=history,
                      notes=notes)
