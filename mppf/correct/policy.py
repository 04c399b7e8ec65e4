"""How large the next correction may be and where it starts: the step policy, from what the plate has shown.

The learned correction (:func:`mppf.correct.learned.learned_correction`) predicts what its
strokes will do to the plate and learns the plate's response per smooth mode and per punch
from every secant (:class:`mppf.correct.secant.ModeGain`). Whether a correction delivered is
measured one cycle later. The policy turns that into the next step:

- **measured response** ``rho`` of each correction: the plate's measured change at the
  punches against the change the correction promised there (the secant of what the plate
  moved vs what the strokes asked), a least-squares ratio regularised towards 1 by the
  scan's noise: ``rho = (sum p m + n s^2) / (sum p^2 + n s^2)`` over the n punches, ``p`` the
  promised change, ``m`` the measured one, ``s`` the noise of a punch deviation. Promises
  within the noise teach nothing (``rho`` stays near 1). It is measured separately at the
  outer ring of punches (a free edge carries no moment and answers differently) and inside it,
  and reported with the correction;
- **the share of the way**: 1. A correction that did not deliver (the excess over the
  tolerances grew past the best one seen, or the plate moved against the promise,
  ``rho <= 0``) is followed by a smaller, safer one, half the last share, started from the
  strokes of the best cycle so far (:attr:`StepPlan.base`), not from the ones that made the
  plate worse; a correction that delivered doubles the share back, up to 1.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

RESPONSE_RANGE = (0.25, 4.0)
"""The plate's answer to the model's prediction the loop is built for: a third to three times (with margin)."""

MIN_SHARE = 0.125
"""Smallest share of the way: three halvings (a step that small no longer crosses a plate's elastic stretch)."""

DEFAULT_NOISE_MM = 0.3
"""Noise of a punch deviation (mm) when the scan gives none (the simulated scanner's point noise)."""


@dataclass(frozen=True, eq=False)
class Outcome:
    """One measured cycle, as the policy sees it.

    Attributes
    ----------
    form_max_mm, rms_mm : float
        Largest absolute and RMS deviation over the net plate (mm).
    error_mm : (rows, cols) float
        Deviation at the punches (mm; NaN where unknown or inactive).
    promised_mm : (rows, cols) float or None
        The deviation at the punches the correction that made this cycle predicted (None for
        the first cycle, or unknown).
    """

    form_max_mm: float
    rms_mm: float
    error_mm: np.ndarray
    promised_mm: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class StepPlan:
    """The size of the next correction and where it starts.

    Attributes
    ----------
    share : float
        Share of the way to ask for, in (0, 1].
    base : int
        Index of the cycle whose final strokes the next strokes start from (the last one,
        or the best one after a correction that made the plate worse).
    ratios : list of float
        Measured over promised change of each correction so far (inside the outer punches).
    edge_ratios : list of float
        The same at the outer punches.
    backtrack : bool
        The last correction made the plate worse.
    notes : list of str
    """

    share: float = 1.0
    base: int = -1
    ratios: list = field(default_factory=list)
    edge_ratios: list = field(default_factory=list)
    backtrack: bool = False
    notes: list = field(default_factory=list)


def outer_ring(active) -> np.ndarray:
    """The first and last active punch of every row and column (rows, cols bool)."""
    act = np.asarray(active, dtype=bool)
    ring = np.zeros_like(act)
    for axis in (0, 1):
        idx = np.arange(act.shape[axis])
        shape = [1, 1]
        shape[axis] = -1
        pos = np.where(act, idx.reshape(shape), -1)
        last = pos.max(axis=axis, keepdims=True)
        first = np.where(act, idx.reshape(shape), act.shape[axis]).min(axis=axis, keepdims=True)
        ring |= act & ((pos == last) | (pos == first))
    return ring


def excess(outcome: Outcome, tolerance_mm: float, rms_tolerance_mm: float) -> float:
    """How far a cycle is out of tolerance: the larger of form max / tolerance and RMS / RMS tolerance."""
    return max(outcome.form_max_mm / tolerance_mm, outcome.rms_mm / rms_tolerance_mm)


def response_ratio(promised_mm, measured_mm, noise_mm: float) -> float:
    """Measured over promised change (least squares, regularised to 1 by the noise; see the module docstring).

    Parameters
    ----------
    promised_mm, measured_mm : (n,) float
        Promised and measured change at the same punches (mm; NaN entries are left out).
    noise_mm : float
        Noise of one measured value (mm).
    """
    p, m = np.asarray(promised_mm, dtype=float).ravel(), np.asarray(measured_mm, dtype=float).ravel()
    ok = np.isfinite(p) & np.isfinite(m)
    prior = ok.sum() * noise_mm**2
    return float((np.sum(p[ok] * m[ok]) + prior) / (np.sum(p[ok] ** 2) + prior)) if ok.any() else 1.0


def step_plan(outcomes, ring, tolerance_mm: float, rms_tolerance_mm: float,
              noise_mm: float = DEFAULT_NOISE_MM) -> StepPlan:
    """The next correction's scale and base from every measured cycle (see the module docstring).

    Parameters
    ----------
    outcomes : list of Outcome
        Every measured cycle, the first one first.
    ring : (rows, cols) bool
        The outer ring of active punches (first and last of each row and column).
    tolerance_mm, rms_tolerance_mm : float
        The tolerances (mm).
    noise_mm : float
        Noise of a punch deviation (mm).

    Returns
    -------
    StepPlan
    """
    ring = np.asarray(ring, dtype=bool)
    sizes = [excess(o, tolerance_mm, rms_tolerance_mm) for o in outcomes]
    share, ratios, edge_ratios, notes, backtrack = 1.0, [], [], [], False
    for k in range(1, len(outcomes)):
        before, after = outcomes[k - 1], outcomes[k]
        if after.promised_mm is None:
            continue
        promised = after.promised_mm - before.error_mm
        measured = after.error_mm - before.error_mm
        rho = response_ratio(promised[~ring], measured[~ring], noise_mm)
        rho_edge = response_ratio(promised[ring], measured[ring], noise_mm)
        ratios.append(rho), edge_ratios.append(rho_edge)
        worse = sizes[k] > min(sizes[:k])
        backtrack = worse or rho <= 0.0
        share = max(MIN_SHARE, 0.5 * share) if backtrack else min(1.0, 2.0 * share)
        notes.append(f"correction {k}: the plate moved {rho:.2f} x what was promised inside the outer punches, "
                     f"{rho_edge:.2f} x at them" + ("; it made the plate worse" if worse else ""))
    base = int(np.argmin(sizes)) if backtrack else len(outcomes) - 1
    if backtrack:
        notes.append(f"the next strokes start from cycle {base + 1}'s, {share:.0%} of the way")
    return StepPlan(share, base, ratios, edge_ratios, backtrack, notes)
