"""The planner's options: how a plate is planned, as one frozen object.

:func:`mppf.planning.plan.plan_job` (one piece) and :func:`mppf.planning.sectional.plan_plate` (one piece or
sections) take the design and flat points, the press and the thickness, and one :class:`PlanOptions`; the
CLI (``mppf plan``), the batch planner and the loop build it once. The values are checked where the planner
starts (:func:`mppf.planning.plan_steps.check_plan_inputs`, :func:`mppf.forming.material.check_yield_uncertainty`),
so a bad option gives the same message whichever caller built it.
"""

from __future__ import annotations

from dataclasses import dataclass

from mppf.model.material import Material


@dataclass(frozen=True)
class PlanOptions:
    """How to plan a plate (every field has the default of a plain ``mppf plan``).

    Attributes
    ----------
    steps : int or None
        Number of press steps from flat to the target; None (default): the fewest within the
        press's dimpling limit (:func:`mppf.planning.steps.steps_needed`).
    material : Material or None
        Nominal plate material; needed for ``springback`` (default None: no material recorded).
    springback : bool
        Pre-compensate springback (default False): over-bend the principal arcs, then refine the
        strokes by virtual press cycles on the plate model
        (:func:`mppf.correct.virtual_cycles.refine_strokes`).
    yield_uncertainty_pct : float
        With ``springback``: the declared scatter of the yield stress, +- % in [0, 50) (default 0).
        The first press is compensated for the weakest plate of the range, so every plate within it
        is under-bent, never over-bent.
    margin_mm : float or None
        Trim margin, mm: the flat plate is cut with this excess band around its net outline and
        trimmed after forming; None (default): the press's ``[forming] margin_mm``.
    transition_mm : float or None
        Plates larger than the bed only: the least width two neighbouring sections share, mm;
        None (default): :data:`mppf.planning.sections.TRANSITION_PITCHES` punch pitches.
    """

    steps: int | None = None
    material: Material | None = None
    springback: bool = False
    yield_uncertainty_pct: float = 0.0
    margin_mm: float | None = None
    transition_mm: float | None = None
