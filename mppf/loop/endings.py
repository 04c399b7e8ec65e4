"""How a plate's loop ended, in words and as data: why, which region, what the operator should do.

Every ending of :func:`mppf.loop.cycle.run_loop` (``in_tolerance``, ``needs_review``,
``cannot_converge``, ``diverged``, ``max_cycles``, ``badly_formed``) gets an :class:`Ending`:
the reason with the figures that decided, the region of the largest form deviation of the
last scan (design u, v, and whether it lies near the net plate's edge), what to do next, and
the exit code of ``mppf loop`` (:data:`mppf.measure.decision.EXIT_CODES`: 0 in tolerance, 5 not
brought into tolerance, 6 needs review). ``mppf loop --json`` prints it as ``ending`` and its
text as ``verdict`` (never null).
"""

from __future__ import annotations

from dataclasses import dataclass

from mppf.loop.settings import LoopSettings
from mppf.loop.states import Decision
from mppf.measure.decision import (
    EXIT_IN_TOLERANCE,
    EXIT_NEEDS_REVIEW,
    EXIT_OUT_OF_TOLERANCE,
)

ADVICE = {
    Decision.IN_TOLERANCE: "take the plate off the press and trim its margin",
    Decision.NEEDS_REVIEW: ("look at the spots the comparison flags (set-aside points beyond the tolerance, areas "
                            "not measured): rescan them or measure them by hand, then pass or reject the plate"),
    Decision.DIVERGED: ("do not press this plate again with the loop: check that it lies on its marks and has not "
                        "slipped, the scan's registration and the punches' read-back; then finish the region by hand "
                        "or restart the plate from a new plan"),
    Decision.MAX_CYCLES: ("finish the region by hand, or run a new loop on the plate with more --max-cycles "
                          "(the best cycle's figures are above)"),
    Decision.CANNOT_CONVERGE: "see the reason: it names what stands in the way",
    Decision.BADLY_FORMED: ("stop: look at the press, the plan and the scan before pressing anything again "
                            "(a wrong job, a plate laid wrongly, a wrong press description)"),
}
"""What the operator should do after each ending (a cannot-converge verdict brings its own advice)."""


@dataclass(frozen=True)
class Ending:
    """How the loop of a plate ended.

    Attributes
    ----------
    decision : str
        The ending (:class:`mppf.loop.states.Decision`).
    why : str
        What decided, with the figures.
    region : str
        Where the largest form deviation of the last scan lies ("" when unknown).
    advice : str
        What the operator should do.
    exit_code : int
        Exit code of ``mppf loop``.
    """

    decision: str
    why: str
    region: str
    advice: str
    exit_code: int

    @property
    def text(self) -> str:
        """One line for the operator."""
        where = f"; where: {self.region}" if self.region else ""
        return f"{str(self.decision).replace('_', ' ')}: {self.why}{where}; what to do: {self.advice}"

    def to_dict(self) -> dict:
        """JSON-able: decision, why, region, advice, exit_code, text."""
        return {"decision": str(self.decision), "why": self.why, "region": self.region, "advice": self.advice,
                "exit_code": self.exit_code, "text": self.text}


def exit_code(decision) -> int:
    """Exit code of ``mppf loop`` for an ending: 0 in tolerance, 6 needs review, 5 every other ending."""
    if decision == Decision.IN_TOLERANCE:
        return EXIT_IN_TOLERANCE
    if decision == Decision.NEEDS_REVIEW:
        return EXIT_NEEDS_REVIEW
    return EXIT_OUT_OF_TOLERANCE


def ending(decision, cycles, settings: LoopSettings, detail=None, reach: dict | None = None) -> Ending:
    """The ending of a plate's loop from its cycle records.

    Parameters
    ----------
    decision : Decision
        How the loop ended (the last cycle's decision or the plate's status).
    cycles : list of CycleRecord
        Every cycle of the plate, the last one last.
    settings : LoopSettings
    detail : str or mppf.correct.verdict.Verdict, optional
        The rescans' own verdict text (a rescan not taken), or the correction's verdict (cannot
        converge: its reason and its advice).
    reach : dict, optional
        What the plan said the press can make (:meth:`mppf.forming.reach.Reach.to_dict`): a plate not in
        tolerance whose plan said the tolerance may not be reached says so.

    Returns
    -------
    Ending
    """
    decision = Decision(decision)
    measured = [c for c in cycles if c.rms_mm is not None and c.max_abs_mm is not None]
    why, advice = _why(decision, measured, settings), ADVICE[decision]
    if hasattr(detail, "advice"):  # the correction's verdict: its reason and its advice
        why, advice = f"{why}; {detail.reason}", detail.advice
    elif detail:
        why = f"{why}; {detail}"
    if reach and not reach.get("reachable", True) and exit_code(decision) == EXIT_OUT_OF_TOLERANCE:
        why = f"{why}; the plan said so: {reach.get('text', '')}"
    return Ending(str(decision), why, _region(measured[-1] if measured else None), advice, exit_code(decision))


def _figures(c) -> str:
    return f"cycle {c.cycle}: form max {c.max_abs_mm:.2f} mm, RMS {c.rms_mm:.2f} mm"


def _why(decision: Decision, measured, settings: LoopSettings) -> str:
    """What decided, with the figures of the last (and the best) cycle."""
    if not measured:
        return "no cycle was measured"
    last = measured[-1]
    limits = f"(limits {settings.tolerance_mm:g} mm form max, {settings.rms_tolerance_mm:g} mm RMS)"
    best = min(measured, key=lambda c: max(c.max_abs_mm / settings.tolerance_mm, c.rms_mm / settings.rms_tolerance_mm))
    best_text = "" if best is last else f"; the best was {_figures(best)}"
    if decision == Decision.IN_TOLERANCE:
        return f"{_figures(last)} {limits}"
    if decision == Decision.NEEDS_REVIEW:
        reasons = ((last.comparison or {}).get("verdict") or {}).get("reasons") or []
        return f"{_figures(last)} within {limits}, but " + ("; ".join(reasons) or "the inspection needs a person")
    if decision == Decision.DIVERGED:
        rms = " -> ".join(f"{c.rms_mm:.2f}" for c in measured[-3:])
        return (f"{_figures(last)}: the RMS deviation grew ({rms} mm; stop at {settings.divergence_factor:g} x "
                f"the best in two cycles running, or growth in two cycles running){best_text}")
    if decision == Decision.MAX_CYCLES:
        return f"{settings.max_cycles} cycles pressed, {_figures(last)} {limits}{best_text}"
    if decision == Decision.BADLY_FORMED:
        return f"{_figures(last)}: the plate is far from its design everywhere"
    return f"{_figures(last)} {limits}{best_text}"


def _region(record) -> str:
    """Where the last scan's largest form deviation lies, from its stored comparison ("" when unknown)."""
    form = ((record.comparison or {}) if record is not None else {}).get("form") or {}
    peak, uv = form.get("peak_mm"), form.get("peak_uv_mm")
    if peak is None or not uv:
        return ""
    return f"largest form deviation {float(peak):+.2f} mm at design u, v = {float(uv[0]):.0f}, {float(uv[1]):.0f} mm"
