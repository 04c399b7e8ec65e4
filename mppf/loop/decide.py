"""The decision after a compared cycle: in tolerance, needs review, badly formed, diverged, out of cycles, or go on."""

from __future__ import annotations

from mppf.loop.settings import LoopSettings
from mppf.loop.states import Decision
from mppf.measure.decision import NEEDS_REVIEW, Limits, Verdict, within_limits

GROWTH_MARGIN_MM = 0.1
"""An RMS increase below this is scan noise, not growth (for the divergence rule)."""


def decide(rms_history_mm: list[float], max_abs_mm: float, cycle: int, settings: LoopSettings,
           set_aside_beyond: int = 0, verdict: Verdict | None = None) -> Decision:
    """The decision after a compared cycle.

    Parameters
    ----------
    rms_history_mm : list of float
        RMS deviation of every cycle so far, the current one last.
    max_abs_mm : float
        Largest absolute form deviation of the current cycle
        (:attr:`mppf.measure.result.Comparison.form_max_abs_mm`).
    cycle : int
        The current cycle (1-based).
    settings : LoopSettings
    set_aside_beyond : int
        Points of the scan set aside as scanner artefacts that lie beyond the tolerance.
    verdict : Verdict, optional
        The comparison's verdict (:attr:`mppf.measure.result.Comparison.verdict`): "needs
        review" there (set-aside points beyond the tolerance, areas of the net plate not
        measured) stops the loop for review when the form and the RMS are within their
        limits; a badly formed plate stops it (BADLY_FORMED).

    Returns
    -------
    Decision
        BADLY_FORMED when the verdict says the plate is far from its design but is this plate
        (:mod:`mppf.measure.same_plate`: its outline and shape are the design's): the loop
        stops, a person looks at the press, the plan and the scan before anything is pressed
        again. IN_TOLERANCE when the form maximum and the RMS are both within their limits and no
        point set aside as a scanner artefact lies beyond the tolerance and the whole net
        plate was measured; NEEDS_REVIEW when they are within their limits but such points
        exist or the verdict needs review (the loop stops: a person looks at them, the
        plate is never declared in tolerance over them)
        (the one decision rule's measured part:
        :func:`mppf.measure.decision.within_limits`, as ``mppf compare`` decides); DIVERGED when the RMS (the robust measure: the largest deviation of
        a scan is one noisy point) is more than ``divergence_factor`` times the best one
        before it in two cycles running (one such cycle is followed by half a step from
        the best cycle's strokes, :mod:`mppf.correct.policy`: only when that does not
        recover either has the loop diverged), or grew two cycles in a row, each time by
        more than :data:`GROWTH_MARGIN_MM` (the scan's noise floor); MAX_CYCLES when no
        cycles are left; else CONTINUE.
    """
    e = [float(v) for v in rms_history_mm]
    if verdict is not None and verdict.badly_formed:
        return Decision.BADLY_FORMED
    if within_limits(float(max_abs_mm), e[-1], Limits(settings.tolerance_mm, settings.rms_tolerance_mm)):
        review = set_aside_beyond or (verdict is not None and verdict.kind == NEEDS_REVIEW)
        return Decision.NEEDS_REVIEW if review else Decision.IN_TOLERANCE
    factor = settings.divergence_factor
    if len(e) >= 3 and e[-1] > settings.rms_tolerance_mm and all(e[k] > factor * min(e[:k]) for k in (-1, -2)):
        return Decision.DIVERGED
    if len(e) >= 3 and e[-1] > e[-2] + GROWTH_MARGIN_MM and e[-2] > e[-3] + GROWTH_MARGIN_MM:
        return Decision.DIVERGED
    if cycle >= settings.max_cycles:
        return Decision.MAX_CYCLES
    return Decision.CONTINUE
