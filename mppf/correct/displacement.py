"""Displacement adjustment with a secant gain per punch (the "modified DA").

After a press cycle the plate is scanned and compared; ``e`` is the plate's deviation
from the design at each punch, measured along the stroke direction (press z):
``e > 0`` means the formed plate lies ABOVE the design there. The next strokes are

    h_next = h - lambda * e          (displacement adjustment, DA)

applied to both matrices alike (upper and lower tips move by the same amount, so the
gap stays the plate thickness). ``lambda`` is the inverse of the stroke-to-shape gain
``de/dh``. From the second cycle on it is estimated per punch by the secant of the last
two cycles,

    lambda_ij = (h_k - h_{k-1}) / (e_k - e_{k-1}),

clipped to [0.5, 3] and averaged half and half with the plate-wide least-squares secant
(the plate couples neighbouring punches, which makes a punch's own secant noisy). Where a
punch's own secant is unreliable (a stroke or deviation change below 0.1 mm, or a negative
estimate) the plate-wide one is used, and the default gain where that fails too.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from mppf.core.errors import InputError
from mppf.correct.result import PreviousCycle, Step, punch_grid
from mppf.model.press import PressConfig

GAIN_RANGE = (0.5, 3.0)
"""Range the secant gain is clipped to."""

SECANT_MIN_MM = 0.1
"""Smallest stroke change and deviation change between cycles that gives a secant gain."""

SECANT_BLEND = 0.5
"""Weight of a punch's own secant gain against the plate-wide secant gain."""


def displacement_step(press: PressConfig, lower_mm, punch_error_mm, active, *, gain: float,
                      previous: PreviousCycle | Mapping | None) -> Step:
    """The DA step ``-lambda e``: lambda the default gain, or the secant gain with a previous cycle.

    Parameters
    ----------
    press : PressConfig
    lower_mm : (rows, cols) float
        Lower tip heights pressed in the cycle just measured.
    punch_error_mm : (rows, cols) float
        Measured deviation at the punches, positive = plate above the design (NaN: unknown).
    active : (rows, cols) bool
    gain : float
        Default lambda (> 0).
    previous : PreviousCycle or mapping with ``lower_mm`` and ``punch_error_mm``, optional

    Returns
    -------
    Step
        Acting where the punch is active and its error known.
    """
    error = np.asarray(punch_error_mm, dtype=float)
    known = active & np.isfinite(error)
    lam = np.where(active, float(gain), np.nan)
    notes: list[str] = []
    if previous is not None:
        lam, fallback = secant_gain(press, lower_mm, error, previous, float(gain), known)
        lam = np.where(active, lam, np.nan)
        notes.append(f"own secant gain at {int((known & ~fallback).sum())} punches, plate-wide or default at "
                     f"{int((known & fallback).sum())}; gain range {np.nanmin(lam[known]) if known.any() else gain:.2f}"
                     f"..{np.nanmax(lam[known]) if known.any() else gain:.2f}")
    wanted = np.where(known, -lam * np.where(known, error, 0.0), 0.0)
    return Step(wanted_mm=wanted, known=known, gain=lam, notes=notes)


def secant_gain(press: PressConfig, lower_mm, punch_error_mm, previous, default: float,
                known) -> tuple[np.ndarray, np.ndarray]:
    """Per-punch secant gain, blended with the plate-wide one; and where the punch's own fell back.

    The per-punch secant ``dh / de`` is noisy where neighbouring punches changed too (the
    plate couples them), so it is averaged half and half with the plate-wide least-squares
    secant ``sum(dh de) / sum(de^2)``. Punches without a usable secant of their own take the
    plate-wide one (or the default when that is unusable too).

    Returns
    -------
    gain : (rows, cols) float
    fallback : (rows, cols) bool
        Where the punch's own secant was not usable.

    Raises
    ------
    InputError
        A mapping without ``lower_mm`` or ``punch_error_mm``, or grids of another shape.
    """
    if isinstance(previous, Mapping):
        try:
            previous = PreviousCycle(lower_mm=previous["lower_mm"], punch_error_mm=previous["punch_error_mm"])
        except KeyError as exc:
            raise InputError(f"previous cycle lacks {exc}", hint="give lower_mm and punch_error_mm") from None
    lower_prev = punch_grid(press, previous.lower_mm, "previous lower_mm")
    error_prev = punch_grid(press, previous.punch_error_mm, "previous punch_error_mm")
    dh = np.asarray(lower_mm, dtype=float) - lower_prev
    de = np.asarray(punch_error_mm, dtype=float) - error_prev
    with np.errstate(invalid="ignore", divide="ignore"):
        secant = dh / de
    ok = known & np.isfinite(secant) & (np.abs(dh) >= SECANT_MIN_MM) & (np.abs(de) >= SECANT_MIN_MM) & (secant > 0)
    plate_wide = default
    if ok.sum() >= 3:
        estimate = float(np.sum(dh[ok] * de[ok]) / np.sum(de[ok] ** 2))
        if estimate > 0:
            plate_wide = float(np.clip(estimate, *GAIN_RANGE))
    own = np.clip(np.where(ok, secant, default), *GAIN_RANGE)
    lam = np.where(ok, SECANT_BLEND * own + (1.0 - SECANT_BLEND) * plate_wide, plate_wide)
    return lam, ~ok
