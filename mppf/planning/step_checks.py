"""The checks of one press step against the press, as :func:`mppf.planning.validate.validate_steps` runs them.

A step is checked in the order the problems are listed: every active stroke within the stroke limits of
its matrix, the tip gap of every active pair at least the thickness, then per matrix no step adding more
than the dimpling limit to the height difference of neighbouring punches and no punch reversing its
direction. :class:`StepTrack` carries what one step leaves for the next (the strokes so far, the
direction of each punch) and the figures of the validation report.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from mppf.core.grid import neighbour_differences
from mppf.model.job_parts import StepStrokes
from mppf.model.press import PressConfig
from mppf.planning.steps import flat_heights

GAP_TOLERANCE_MM = 0.01
"""The tip gap of a punch pair may be this much below the thickness (rounding)."""
LIMIT_TOLERANCE_MM = 1e-6
SIDES = ("upper", "lower")


@dataclass
class StepTrack:
    """What the steps checked so far leave for the next one, and the figures measured.

    Attributes
    ----------
    prev : dict of str -> (rows, cols) float
        Per matrix the stroke of each punch after the last step that moved it, mm (the flat plate's
        heights before the first step).
    direction : dict of str -> (rows, cols) float
        Per matrix the sign of each punch's last move (0: not moved yet).
    min_gap_mm : float
        Smallest tip gap of an active pair so far (inf: none yet).
    max_step_diff_mm : float
        Largest change of a neighbour height difference in one step so far, mm.
    label : callable
        (row, col) -> the punch's name as the press labels it (:meth:`PressConfig.punch_label`).
    """

    prev: dict
    direction: dict
    min_gap_mm: float = math.inf
    max_step_diff_mm: float = 0.0
    label: object = field(default=None, repr=False)

    @classmethod
    def start(cls, press: PressConfig, thickness_mm: float) -> StepTrack:
        """Before the first step: every punch at its flat-plate height (upper t, lower 0), not moved."""
        flat = dict(zip(SIDES, flat_heights(thickness_mm)))
        return cls(prev={side: np.full(press.shape, flat[side]) for side in SIDES},
                   direction={side: np.zeros(press.shape) for side in SIDES}, label=press.punch_label)


def check_step(k: int, step: StepStrokes, press: PressConfig, limits: dict, thickness_mm: float, problems,
               track: StepTrack) -> None:
    """Check step ``k`` (1-based): its problems go to ``problems.add``, its figures and strokes to ``track``.

    ``limits`` maps each matrix to its (min, max) stroke in mm
    (:func:`mppf.planning.validate.stroke_limits`); ``thickness_mm`` is the plate thickness.
    """
    act = np.asarray(step.active, bool)
    values = {"upper": step.upper_mm, "lower": step.lower_mm}
    label = track.label
    for side, (lo, hi) in limits.items():
        v = values[side]
        bad = act & ((v < lo - LIMIT_TOLERANCE_MM) | (v > hi + LIMIT_TOLERANCE_MM) | ~np.isfinite(v))
        problems.add(f"step {k} {side} punch ({label(r, c)}): stroke {v[r, c]:.2f} mm beyond the stroke limits "
                     f"{lo:g}..{hi:g} mm" for r, c in np.argwhere(bad))
    gap = np.where(act, step.upper_mm - step.lower_mm, np.inf)
    if act.any():
        track.min_gap_mm = min(track.min_gap_mm, float(gap[act].min()))
    problems.add(f"step {k} punch pair ({label(r, c)}): tip gap {gap[r, c]:.2f} mm < thickness {thickness_mm:g} mm"
                 for r, c in np.argwhere(act & (gap < thickness_mm - GAP_TOLERANCE_MM)))
    for side in SIDES:
        _check_moves(k, side, values[side], act, press.max_neighbour_diff_mm, problems, track)


def _check_moves(k: int, side: str, values, act, dimpling_mm: float, problems, track: StepTrack) -> None:
    """One matrix's moves in step ``k``: the dimpling limit ``dimpling_mm`` between neighbours and monotonic
    strokes; ``values`` (rows, cols) strokes in mm, ``act`` (rows, cols) bool."""
    label, prev = track.label, track.prev[side]
    for diff, first, second in neighbour_differences(values - prev, act):
        if diff.size:
            track.max_step_diff_mm = max(track.max_step_diff_mm, float(np.nanmax(np.abs(diff), initial=0.0)))
        bad = np.abs(diff) > dimpling_mm + LIMIT_TOLERANCE_MM
        problems.add(f"step {k} {side} punches ({label(*a)}) and ({label(*b)}): the height difference "
                     f"changes by {d:+.2f} mm, dimpling limit {dimpling_mm:g} mm"
                     for d, a, b in zip(diff[bad], first[bad], second[bad]))
    move = np.where(act, values - prev, 0.0)
    back = act & (move * track.direction[side] < -LIMIT_TOLERANCE_MM)
    problems.add(f"step {k} {side} punch ({label(r, c)}) reverses direction: moves {move[r, c]:+.2f} mm "
                 "after moving the other way (strokes must be monotonic from step to step)"
                 for r, c in np.argwhere(back))
    track.direction[side] = np.where(np.abs(move) > LIMIT_TOLERANCE_MM, np.sign(move), track.direction[side])
    track.prev[side] = np.where(act & np.isfinite(values), values, prev)
