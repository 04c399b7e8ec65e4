"""The loop's one correction: the step policy, the learned correction and its verdict, in one call.

:func:`correct_step` is what :mod:`mppf.loop.correcting` does after a compared cycle and what
``benchmarks/bench_loop.py`` measures: the size and base of the next step from what the plate
showed (:func:`mppf.correct.policy.step_plan`), the strokes from the learned correction
(:func:`mppf.correct.learned.learned_correction`) scaled by it, and the verdict when no
step helps (:func:`mppf.correct.verdict.convergence_verdict`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from mppf.correct.inputs import CorrectedPlate, CorrectionHistory
from mppf.correct.learned import LearnedCorrection, learned_correction
from mppf.correct.policy import (
    DEFAULT_NOISE_MM,
    Outcome,
    StepPlan,
    outer_ring,
    step_plan,
)
from mppf.correct.verdict import Verdict, convergence_verdict


@dataclass(frozen=True, eq=False)
class CorrectionStep:
    """The next strokes, the plan that sized them, and the verdict (None: press them).

    Attributes
    ----------
    learned : LearnedCorrection
    plan : StepPlan
    verdict : Verdict or None
    """

    learned: LearnedCorrection
    plan: StepPlan
    verdict: Verdict | None


@dataclass(frozen=True)
class Tolerances:
    """The tolerances and the scan's noise the step is judged by (mm)."""

    tolerance_mm: float
    rms_tolerance_mm: float
    noise_mm: float = DEFAULT_NOISE_MM


def correct_step(plate: CorrectedPlate, history: CorrectionHistory, tolerances: Tolerances,
                 policy: bool = True) -> CorrectionStep:
    """The next strokes from every pressed and measured cycle, sized by what the plate showed.

    Parameters
    ----------
    plate : CorrectedPlate
        The press, the design's mid-surface heights at the punches, thickness, the material the planner
        assumed, the active punches.
    history : CorrectionHistory
        Every cycle as the press did it and as it was measured, the same cycles as the policy sees them
        (form max, RMS, punch deviation, promise), each measured cycle's final strokes as planned, and the
        net plate's edge beyond the outer punches after the last cycle (or None).
    tolerances : Tolerances
    policy : bool
        False: every step at full size from the last strokes (to measure what the policy does).

    Returns
    -------
    CorrectionStep
    """
    outcomes = history.outcomes
    ring = outer_ring(plate.active)
    plan = (step_plan(outcomes, ring, tolerances.tolerance_mm, tolerances.rms_tolerance_mm, tolerances.noise_mm)
            if policy else StepPlan())
    upper, lower = history.strokes[plan.base]

    def correct(share):
        return learned_correction(plate, history.cycles, upper, lower, edge_mm=history.edge_mm,
                                  scale=np.full(ring.shape, share))

    learned = correct(plan.share)
    if len(outcomes) > 1:
        plan, learned = _safer_near_tolerance(plan, learned, outcomes[-1], tolerances, correct)
    learned.notes.extend(plan.notes)
    verdict = convergence_verdict([o.rms_mm for o in outcomes], learned.predicted_rms_mm,
                                  tolerances.rms_tolerance_mm, clipped=int(learned.clipped.sum()),
                                  unreached=int(learned.unreached.sum()), max_mm=[o.form_max_mm for o in outcomes],
                                  tolerance_mm=tolerances.tolerance_mm, share=plan.share)
    return CorrectionStep(learned, plan, verdict)


def _safer_near_tolerance(plan: StepPlan, learned: LearnedCorrection, now: Outcome, tolerances: Tolerances, correct):
    """Half the step when only the form max is out, the full step promises more change than the error, half is enough.

    A correction whose promised change at the punches (RMS) exceeds the deviation it removes
    plans to carry the plate past the design there (the outer rows aimed towards the edge beyond
    them, a local ratio learned from one secant); a plate answering more than promised then ends
    the cycle worse, and the way back needs a reverse bend. When the RMS is already within its
    tolerance (only the form max is out) and half the share is already
    predicted to bring the plate within the tolerances, that half step is taken instead. The
    prediction is at the punches; the form max also counts what lies beyond them (the net edge,
    between the punches), taken as large as it is now: the form max now less the largest
    deviation at the punches now.

    Parameters
    ----------
    plan : StepPlan
    learned : LearnedCorrection
        The correction at ``plan.share``.
    now : Outcome
        The cycle just measured.
    tolerances : Tolerances
    correct : callable
        ``correct(share) -> LearnedCorrection``, the same correction at another share.

    Returns
    -------
    plan, learned
        Unchanged, or at half the share.
    """
    last = np.asarray(now.error_mm, dtype=float)
    known = np.isfinite(learned.predicted_mm) & np.isfinite(last)
    if not known.any() or now.rms_mm > tolerances.rms_tolerance_mm:
        return plan, learned
    promise = float(np.sqrt(np.mean((learned.predicted_mm - last)[known] ** 2)))
    error = float(np.sqrt(np.mean(last[known] ** 2)))
    if promise <= error:
        return plan, learned
    half = correct(0.5 * plan.share)
    predicted = half.predicted_mm[np.isfinite(half.predicted_mm)]
    beyond = max(0.0, now.form_max_mm - float(np.max(np.abs(last[known]))))
    if predicted.size == 0 or np.max(np.abs(predicted)) + beyond > tolerances.tolerance_mm \
            or np.sqrt(np.mean(predicted**2)) > tolerances.rms_tolerance_mm:
        return plan, learned
    half.notes.append(f"the full step promised a change of {promise:.2f} mm RMS for an error of {error:.2f} mm: "
                      f"half of it, predicted within the tolerances, taken instead")
    return replace(plan, share=0.5 * plan.share), half


def outcome(form_max_mm: float, rms_mm: float, error_mm, promised_mm=None) -> Outcome:
    """An :class:`Outcome` of plain values (``promised_mm`` None for the first cycle)."""
    promised = None if promised_mm is None else np.asarray(promised_mm, dtype=float)
    return Outcome(float(form_max_mm), float(rms_mm), np.asarray(error_mm, dtype=float), promised)
