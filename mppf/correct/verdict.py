"""When the correction cannot bring the plate into tolerance: a verdict that says why and what to do.

The loop stops a plate as "cannot converge" instead of drifting to its cycle limit when
(:func:`convergence_verdict`)

- the correction finds no stroke change that brings the plate much closer (its own
  prediction of the next cycle improves the RMS deviation by less than
  :data:`MIN_PREDICTED_GAIN`): the needed strokes lie beyond the press's stroke limits, or
  beyond the trust region of one correction (an over-bent plate that would need a reverse
  bend further than the press can give), or the measurement does not describe the plate;
- or the measurements show it: two corrections in a row each took less than
  :data:`MIN_MEASURED_GAIN` off the plate's excess over its tolerances (the larger of
  largest deviation / tolerance and RMS / RMS tolerance).
"""

from __future__ import annotations

from dataclasses import dataclass

MIN_PREDICTED_GAIN = 0.10
"""Share of the RMS deviation the next cycle is predicted to remove, below which the correction gives up."""

MIN_MEASURED_GAIN = 0.20
"""Share of the RMS deviation each of the last two corrections must have removed (measured)."""


@dataclass(frozen=True)
class Verdict:
    """Why the loop stops a plate that is not in tolerance, and what the operator should do.

    Attributes
    ----------
    reason : str
        What the correction or the measurements showed.
    advice : str
        What to do next.
    """

    reason: str
    advice: str

    @property
    def text(self) -> str:
        """One line for the operator."""
        return f"cannot converge: {self.reason}; {self.advice}"


def convergence_verdict(rms_mm, predicted_rms_mm: float, rms_tolerance_mm: float, *, clipped: int = 0,
                        unreached: int = 0, max_mm=None, tolerance_mm: float | None = None,
                        share: float = 1.0) -> Verdict | None:
    """The verdict on a plate still out of tolerance, or None when the next cycle is worth pressing.

    Called only for a plate out of tolerance (by its largest or its RMS deviation).

    Parameters
    ----------
    rms_mm : sequence of float
        Measured RMS deviation of every measured cycle so far, the current one last (mm).
    predicted_rms_mm : float
        RMS deviation the correction predicts after the next cycle (mm).
    rms_tolerance_mm : float
        The RMS tolerance (mm).
    clipped : int
        Punches at which the press's stroke limits cut the correction.
    unreached : int
        Punches whose wanted bend lay beyond the correction's trust region.
    max_mm : sequence of float, optional
        Largest (form) deviation of the same cycles (mm), with ``tolerance_mm``.
    tolerance_mm : float, optional
        The tolerance of the largest deviation (mm).
    share : float
        Share of the way the next correction asks for (:attr:`mppf.correct.policy.StepPlan.share`):
        a stall is judged only once a smaller step was tried (share below 1), and the predicted
        improvement against :data:`MIN_PREDICTED_GAIN` times the share.

    Returns
    -------
    Verdict or None
    """
    rms = [float(v) for v in rms_mm]
    now = rms[-1]
    excess = [v / rms_tolerance_mm for v in rms]
    if max_mm is not None and tolerance_mm is not None:
        excess = [max(e, float(m) / tolerance_mm) for e, m in zip(excess, max_mm)]
    stalled = all(b > (1.0 - MIN_MEASURED_GAIN) * a for a, b in zip(excess[-3:], excess[-2:]))
    if len(excess) >= 3 and share < 1.0 and stalled:
        return _stalled(rms, max_mm)
    if predicted_rms_mm > (1.0 - MIN_PREDICTED_GAIN * min(share, 1.0)) * now and predicted_rms_mm > rms_tolerance_mm:
        return _no_way_on(predicted_rms_mm, now, clipped, unreached)
    return None


def _stalled(rms: list[float], max_mm) -> Verdict:
    """The verdict of a measured deviation that no longer falls: ``rms`` (mm) of every measured cycle and their
    largest deviations ``max_mm`` (mm, or None), the last three shown."""
    shown = f"RMS {' -> '.join(f'{v:.2f}' for v in rms[-3:])} mm"
    if max_mm is not None:
        shown += f", largest {' -> '.join(f'{float(v):.2f}' for v in list(max_mm)[-3:])} mm"
    return Verdict(
        f"the measured deviation no longer falls ({shown} over the last two corrections)",
        "check that the plate lies on its marks and has not slipped, that the scans are of this plate and "
        "register well, and the punches; then finish the plate by hand or restart it with a new plan",
    )


def _no_way_on(predicted_rms_mm: float, now: float, clipped: int, unreached: int) -> Verdict:
    """The verdict of a correction that predicts no worthwhile improvement (RMS in mm), and why: the stroke
    limits (``clipped`` punches), the trust region (``unreached`` punches) or neither."""
    if clipped:
        why = f"the strokes it needs lie beyond the press's stroke limits at {clipped} punches"
        what = "lay the plate on the press again with more room (re-plan it), or finish it by hand"
    elif unreached:
        why = (f"the bend it needs at {unreached} punches lies beyond what one correction may ask "
               "(an over-bent region needs a reverse bend larger than the trust region)")
        what = "press the region back by hand (reverse bend), or restart the plate from a flattened state"
    else:
        why = "no stroke change within its trust region brings the plate closer"
        what = ("check the scan (registration, reference mark, occlusions) and the press's read-back; "
                "then finish the plate by hand")
    return Verdict(f"{why} (predicted RMS {predicted_rms_mm:.2f} mm after the next cycle, now {now:.2f} mm)", what)
