"""How large the next correction may be: the step policy, from what the plate has shown.

The learned correction (:func:`mppf.correct.learned.learned_correction`) predicts what its
strokes will do to the plate. Whether the plate does it is measured one cycle later. The
policy turns those measurements into the size of the next step and where it starts:

- **measured response** ``rho`` of each correction: the plate's measured change at the
  punches against the change the correction promised there (the secant of what the plate
  moved vs what the strokes asked), a least-squares ratio regularised towards 1 by the
  scan's noise: ``rho = (sum p m + n s^2) / (sum p^2 + n s^2)`` over the n punches, ``p`` the
  promised change, ``m`` the measured one, ``s`` the noise of a punch deviation. Promises
  within the noise teach nothing (``rho`` stays near 1). It is measured separately at the
  outer ring of punches (the edges answer differently: a free edge carries no moment) and
  inside it, and the next step is scaled per region (:attr:`StepPlan.scale_mm`);
- **scale**: the next request is the last one's scale divided by the measured response (a
  plate that moved twice what was promised is asked half as much; one that moved half, twice
  as much), within :data:`SCALE_RANGE` (the range of responses the loop is built for);
- **a correction that did not deliver** (the excess over the tolerances grew, or the plate
  moved against the promise, ``rho <= 0``) is followed by a smaller, safer one: half the
  smaller of the last scale and the measured one, started from the strokes of the best
  cycle so far (:attr:`StepPlan.base`), not from the ones that made the plate worse.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

SCALE_RANGE = (0.25, 4.0)
"""Smallest and largest scale of a request: the plate's answer may be a third to three times the model's."""

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
    scale : float
        Scale of the request inside the outer ring of punches.
    edge_scale : float
        Scale of the request at the outer ring.
    base : int
        Index of the cycle whose final strokes the next strokes start from (the last one,
        or the best one after a correction that made the plate worse).
    ratios : list of float
        Measured response of each correction so far (inside the ring).
    backtrack : bool
        The last correction made the plate worse.
    notes : list of str
    """

    scale: float = 1.0
    edge_scale: float = 1.0
    base: int = -1
    ratios: list = field(default_factory=list)
    backtrack: bool = False
    notes: list = field(default_factory=list)

    def scale_mm(self, ring) -> np.ndarray:
        """Scale per punch (rows, cols): ``edge_scale`` on the ``ring`` (rows, cols bool), ``scale`` elsewhere."""
        return np.where(np.asarray(ring, dtype=bool), self.edge_scale, self.scale)


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
    scale = edge_scale = 1.0
    ratios, notes, backtrack = [], [], False
    for k in range(1, len(outcomes)):
        before, after = outcomes[k - 1], outcomes[k]
        if after.promised_mm is None:
            continue
        promised = after.promised_mm - before.error_mm
        measured = after.error_mm - before.error_mm
        rho = response_ratio(promised[~ring], measured[~ring], noise_mm)
        rho_edge = response_ratio(promised[ring], measured[ring], noise_mm)
        ratios.append(rho)
        worse = sizes[k] > min(sizes[:k])
        backtrack = worse or rho <= 0.0
        scale = _next_scale(scale, rho, backtrack)
        edge_scale = _next_scale(edge_scale, rho_edge, backtrack)
        notes.append(f"correction {k}: the plate moved {rho:.2f} x what was promised inside the outer punches, "
                     f"{rho_edge:.2f} x at them" + ("; it made the plate worse" if worse else ""))
    base = int(np.argmin(sizes)) if backtrack else len(outcomes) - 1
    if backtrack:
        notes.append(f"the next strokes start from cycle {base + 1}'s (the best so far), at scale {scale:.2f}")
    return StepPlan(scale, edge_scale, base, ratios, backtrack, notes)


def _next_scale(scale: float, rho: float, smaller: bool) -> float:
    """The next request's scale: the last one over the measured response; halved (and never larger) when ``smaller``."""
    measured = scale / rho if rho > 0.0 else scale
    nxt = 0.5 * min(scale, measured) if smaller else measured
    return float(np.clip(nxt, *SCALE_RANGE))
