"""What a correction takes: the plate and press it is for, and what the plate went through so far.

:func:`mppf.correct.step.correct_step` (the loop's one correction) takes one :class:`CorrectedPlate` and
one :class:`CorrectionHistory`; :func:`mppf.correct.learned.learned_correction` the same plate. The loop
(:mod:`mppf.loop.correcting`, :mod:`mppf.loop.sectional`) and the loop benches build them from the
plate's recorded cycles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.model.material import Material
from mppf.model.press import PressConfig


@dataclass(frozen=True, eq=False)
class CorrectedPlate:
    """The plate a correction is for, on its press.

    Attributes
    ----------
    press : PressConfig
        The press (its stroke limits hold the corrected strokes, its dimpling limit their steps).
    design_mid_mm : (rows, cols) float
        The design's mid-surface height at the punches, mm (``Job.layout.design_mid_mm``).
    thickness_mm : float
        Plate thickness, mm.
    nominal : Material
        The material the planner assumed (the plate model starts from it).
    active : (rows, cols) bool
        The punches under the plate.
    """

    press: PressConfig
    design_mid_mm: np.ndarray
    thickness_mm: float
    nominal: Material
    active: np.ndarray


@dataclass(frozen=True, eq=False)
class CorrectionHistory:
    """What the plate went through: every cycle as pressed and measured.

    Attributes
    ----------
    cycles : list of PressedCycle
        Every cycle as the press did it and as it was measured (:class:`mppf.correct.memory.PressedCycle`).
    outcomes : list of Outcome
        The measured cycles as the step policy sees them (form max, RMS, punch deviation, promise;
        :class:`mppf.correct.policy.Outcome`).
    strokes : list of tuple of (rows, cols) float
        Each measured cycle's final (upper, lower) strokes as planned, mm.
    edge_mm : (rows, cols) float or None
        The net plate's edge beyond the outer punches after the last cycle, mm (None: not known).
    """

    cycles: list
    outcomes: list
    strokes: list
    edge_mm: np.ndarray | None = None
