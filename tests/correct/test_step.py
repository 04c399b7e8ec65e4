"""The half step near the tolerance (mppf.correct.step._safer_near_tolerance)."""

from __future__ import annotations

import numpy as np

from mppf.correct.learned import LearnedCorrection
from mppf.correct.policy import StepPlan
from mppf.correct.step import Tolerances, _safer_near_tolerance, outcome

TOL = Tolerances(2.5, 1.0)


def _learned(predicted_mm) -> LearnedCorrection:
    predicted = np.asarray(predicted_mm, dtype=float)
    zeros = np.zeros_like(predicted)
    return LearnedCorrection(zeros, zeros, 1, zeros, predicted, None, np.ones(1), zeros.astype(bool),
                             zeros.astype(bool), [])


def _grid(value: float) -> np.ndarray:
    return np.full((3, 4), value)


def test_a_promise_within_the_error_is_left_alone():
    asked = []
    now = outcome(1.5, 0.9, _grid(0.9))
    full = _learned(_grid(0.1))  # promises 0.8 mm of change for 0.9 mm of error
    plan, learned = _safer_near_tolerance(StepPlan(), full, now, TOL, lambda s: asked.append(s) or _learned(_grid(0)))
    assert learned is full and plan.share == 1.0 and asked == []


def test_a_promise_past_the_design_is_halved_when_half_is_enough():
    asked = []
    now = outcome(1.5, 0.9, _grid(0.9))
    full = _learned(_grid(-1.2))  # promises 2.1 mm of change for 0.9 mm of error: past the design
    half = _learned(_grid(-0.15))
    plan, learned = _safer_near_tolerance(StepPlan(share=0.5), full, now, TOL, lambda s: asked.append(s) or half)
    assert asked == [0.25]
    assert learned is half and plan.share == 0.25
    assert "half of it" in learned.notes[-1]


def test_the_full_step_stays_when_half_would_not_reach_the_tolerance():
    now = outcome(2.9, 0.9, _grid(0.9))  # the form max lies 2.0 mm beyond what the punches show
    full = _learned(_grid(-1.2))
    half = _learned(_grid(-0.6))  # 0.6 at the punches, 2.6 with what lies beyond them: out of tolerance
    plan, learned = _safer_near_tolerance(StepPlan(), full, now, TOL, lambda s: half)
    assert learned is full and plan.share == 1.0
    rms_out = _learned(_grid(-1.1))  # within the form tolerance but not the RMS one
    plan, learned = _safer_near_tolerance(StepPlan(), full, outcome(1.0, 0.9, _grid(0.9)), TOL, lambda s: rms_out)
    assert learned is full


def test_the_full_step_stays_while_the_rms_is_out_of_tolerance():
    asked = []
    now = outcome(1.5, 1.3, _grid(1.3))
    full = _learned(_grid(-1.5))  # past the design, but the whole plate is still out: the full step
    plan, learned = _safer_near_tolerance(StepPlan(), full, now, TOL, lambda s: asked.append(s) or _learned(_grid(0)))
    assert learned is full and asked == []
