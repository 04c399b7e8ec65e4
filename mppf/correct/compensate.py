"""Stroke compensation on the plate model: the next strokes of one press step from a deviation at the punches.

:func:`compensate` is one virtual cycle's correction in the planner's springback pre-compensation
(:func:`mppf.correct.virtual_cycles.refine_strokes`): the springback-model step with the plate's
nominal material (:mod:`mppf.correct.model_step`), smoothed on the punch grid, then held to the
press's dimpling and stroke limits (:mod:`mppf.correct.limits`). Both matrices move alike, so the
gap stays the plate thickness. The loop corrects a pressed plate with
:func:`mppf.correct.step.correct_step`, not with this.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.grid import neighbour_mean
from mppf.core.validate import check_number
from mppf.correct.limits import limit_correction, limited_notes
from mppf.correct.model_step import MAX_STEP_RATIO, model_step
from mppf.correct.result import Correction, punch_grid
from mppf.model.material import Material
from mppf.model.press import PressConfig

__all__ = ["SMOOTHING", "CompensateOptions", "Correction", "compensate", "limit_correction"]

SMOOTHING = 0.25
"""Weight of the neighbour average in the smoothed correction (0 = none, 1 = only neighbours)."""

GAP_NOTE_MM = 0.5
"""A note is added where the tip gap ``upper - lower`` differs from the thickness by more than this."""


@dataclass(frozen=True)
class CompensateOptions:
    """How :func:`compensate` corrects.

    Attributes
    ----------
    gain : float
        Factor on the springback-model step (:func:`mppf.correct.model_step.model_correction`); > 0
        (default 1).
    smoothing : float
        Weight of the neighbour average in the correction, in [0, 1] (default :data:`SMOOTHING`).
    max_step_ratio : float or None
        Trust region of the model step: scaled down as a whole when a punch would move by more
        than this times the largest measured error (default :data:`mppf.correct.model_step.MAX_STEP_RATIO`);
        None = no limit (the virtual cycles of :mod:`mppf.correct.virtual_cycles`, where the model is its
        own truth).
    """

    gain: float = 1.0
    smoothing: float = SMOOTHING
    max_step_ratio: float | None = MAX_STEP_RATIO


def compensate(upper_mm, lower_mm, punch_error_mm, *, press: PressConfig, thickness_mm: float, material: Material,
               options: CompensateOptions = CompensateOptions()) -> Correction:
    """Correct the strokes of one press step through the springback model from a deviation at the punches.

    Parameters
    ----------
    upper_mm, lower_mm : (rows, cols) float
        Tip heights pressed in the cycle just measured (NaN where inactive).
    punch_error_mm : (rows, cols) float
        Deviation of the (predicted) plate from the design at each punch along press z: positive =
        plate above the design. NaN where unknown (filled from the known ones; no correction
        with fewer than 6 known).
    press : PressConfig
    thickness_mm : float
        Plate thickness; a note is added where the gap ``upper - lower`` differs from it.
    material : Material
        The plate's material the springback model takes.
    options : CompensateOptions
        Gain, smoothing and the trust region of the model step.

    Returns
    -------
    Correction

    Raises
    ------
    InputError
        Wrong shapes, a non-positive gain or a smoothing weight outside [0, 1].
    """
    upper, lower, error, gain, smoothing = _check_inputs(press, upper_mm, lower_mm, punch_error_mm, options.gain,
                                                         options.smoothing)
    active = np.isfinite(upper) & np.isfinite(lower)
    # 1. the wanted change, through the springback model
    step = model_step(upper, lower, error, press=press, thickness_mm=thickness_mm, material=material, gain=gain,
                      max_step_ratio=options.max_step_ratio)
    # 2. smoothed on the punch grid
    smooth = (1.0 - smoothing) * step.wanted_mm + smoothing * neighbour_mean(step.wanted_mm, step.known)
    smooth = np.where(step.known, smooth, 0.0)
    # 3. held to the dimpling limit (neighbour differences of the correction) and the tip heights
    applied, clipped = limit_correction(press, upper, lower, smooth)
    return Correction(
        upper_mm=np.where(active, upper + applied, np.nan),
        lower_mm=np.where(active, lower + applied, np.nan),
        gain=step.gain,
        applied_mm=np.where(active, applied, 0.0),
        clipped=clipped,
        notes=_gap_notes(upper, lower, active, thickness_mm) + step.notes + limited_notes(press, clipped),
    )


def _check_inputs(press: PressConfig, upper_mm, lower_mm, punch_error_mm, gain, smoothing):
    """The three punch grids as arrays of the press's shape, the gain and the smoothing checked."""
    upper, lower, error = (punch_grid(press, a, name) for a, name in
                           ((upper_mm, "upper_mm"), (lower_mm, "lower_mm"), (punch_error_mm, "punch_error_mm")))
    gain = check_number("the model step's gain", gain, low=0.0, low_open=True, hint="1.0 is a safe start")
    smoothing = check_number("smoothing", smoothing, low=0.0, high=1.0)
    return upper, lower, error, gain, smoothing


def _gap_notes(upper, lower, active, thickness_mm: float) -> list[str]:
    """A note when the tip gap of the pressed strokes differs from the plate thickness."""
    gap = (upper - lower)[active]
    if not gap.size or np.max(np.abs(gap - thickness_mm)) <= GAP_NOTE_MM:
        return []
    return [f"gap upper - lower differs from the thickness {thickness_mm:g} mm by up to "
            f"{np.max(np.abs(gap - thickness_mm)):.2f} mm"]
