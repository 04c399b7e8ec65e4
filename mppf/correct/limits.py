"""The press's limits on a correction: the dimpling limit between neighbouring punches and
the tip-height limits of both matrices."""

from __future__ import annotations

import numpy as np

from mppf.core.grid import largest_neighbour_difference
from mppf.model.press import PressConfig

ITERATIONS = 200
"""Most alternating projections before the correction is scaled down as a whole."""


def limit_correction(press: PressConfig, upper_mm, lower_mm, correction_mm) -> tuple[np.ndarray, np.ndarray]:
    """A correction of both matrices held to the press's limits.

    Neighbouring corrections differ by at most the dimpling limit
    (``press.max_neighbour_diff_mm``) and every corrected tip stays within its matrix's
    height limits (alternating projections, :func:`_limit`).

    Parameters
    ----------
    press : PressConfig
    upper_mm, lower_mm : (rows, cols) float
        Tip heights before the correction (NaN where inactive).
    correction_mm : (rows, cols) float
        Wanted change of both matrices (mm).

    Returns
    -------
    applied_mm : (rows, cols) float
        The correction applied (0 where inactive).
    clipped : (rows, cols) bool
        Where the limits reduced it.
    """
    upper = np.asarray(upper_mm, dtype=float)
    lower = np.asarray(lower_mm, dtype=float)
    active = np.isfinite(upper) & np.isfinite(lower)
    wanted = np.where(active, np.asarray(correction_mm, dtype=float), 0.0)
    lo = np.maximum(press.upper.min_mm - upper, press.lower.min_mm - lower)
    hi = np.minimum(press.upper.max_mm - upper, press.lower.max_mm - lower)
    applied = _limit(wanted, active, lo, hi, press.max_neighbour_diff_mm)
    return np.where(active, applied, 0.0), active & (np.abs(applied - wanted) > 1e-9)


def limited_notes(press: PressConfig, clipped) -> list[str]:
    """The operator's note when the limits reduced a correction (none when they did not)."""
    count = int(np.sum(clipped))
    if not count:
        return []
    return [f"correction limited at {count} punches (dimpling limit {press.max_neighbour_diff_mm:g} mm or "
            "stroke limits)"]


def _limit(correction, active, lo, hi, max_diff_mm: float, iterations: int = ITERATIONS) -> np.ndarray:
    """Clip ``correction`` to [lo, hi] and to neighbour differences <= ``max_diff_mm``.

    Alternating projections: each violating neighbour pair is pulled towards its mean,
    then the stroke range is enforced; a final uniform scale-down guarantees both.
    """
    c = np.clip(np.where(active, correction, 0.0), np.where(active, lo, 0.0), np.where(active, hi, 0.0))
    for _ in range(iterations):
        changed = False
        for axis in (0, 1):
            a = np.moveaxis(c, axis, 0)
            act = np.moveaxis(active, axis, 0)
            pair = act[1:] & act[:-1]
            diff = a[1:] - a[:-1]
            excess = np.where(pair, np.abs(diff) - max_diff_mm, 0.0)
            if np.any(excess > 1e-9):
                changed = True
                shift = 0.5 * np.sign(diff) * np.maximum(excess, 0.0) * (1 + 1e-6)
                a[1:] -= shift  # views: modify c in place
                a[:-1] += shift
        c = np.clip(c, np.where(active, lo, 0.0), np.where(active, hi, 0.0))
        if not changed and largest_neighbour_difference(c, active) <= max_diff_mm + 1e-9:
            return c
    # rare: did not settle; shrink towards zero, which satisfies both limits when 0 does
    worst = largest_neighbour_difference(c, active)
    if worst > max_diff_mm:
        c = c * (max_diff_mm / worst)
    return c
