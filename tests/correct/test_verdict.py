"""The verdict of a correction that cannot bring the plate into tolerance: why, and what to do."""

from __future__ import annotations

import pytest

from mppf.correct.verdict import MIN_MEASURED_GAIN, MIN_PREDICTED_GAIN, convergence_verdict


def test_a_plate_that_still_improves_gets_no_verdict():
    assert convergence_verdict([8.0], 1.5, 1.0) is None
    assert convergence_verdict([8.0, 2.0], 0.6, 1.0) is None
    assert convergence_verdict([8.0, 2.0, 1.2], 0.8, 1.0) is None  # 40 % off in the last correction
    # the prediction reaches the tolerance: worth pressing even when it promises little progress
    assert convergence_verdict([1.05], 1.0, 1.0) is None


def test_a_measured_stall_stops_the_plate_with_what_to_check():
    rms = [3.0, 2.9, 2.6]  # two corrections, each less than MIN_MEASURED_GAIN off
    assert convergence_verdict(rms, 1.0, 1.0) is None  # at full share: a smaller step is tried first
    verdict = convergence_verdict(rms, 1.0, 1.0, share=0.5)
    assert verdict is not None and "no longer falls" in verdict.reason
    assert "slipped" in verdict.advice and verdict.text.startswith("cannot converge:")
    # a stall near the tolerance (the largest deviation still out) stops it too
    assert convergence_verdict([0.95, 0.8, 0.78], 0.7, 1.0, share=0.5) is not None
    assert 2.6 / 2.9 > 1 - MIN_MEASURED_GAIN


@pytest.mark.parametrize(("clipped", "unreached", "words"), [
    (12, 0, "stroke limits at 12 punches"), (0, 7, "reverse bend"), (0, 0, "no stroke change"),
])
def test_a_correction_that_finds_no_way_on_says_why(clipped, unreached, words):
    now = 4.0
    stuck = now * (1 - MIN_PREDICTED_GAIN) + 0.01
    verdict = convergence_verdict([10.0, now], stuck, 1.0, clipped=clipped, unreached=unreached)
    assert verdict is not None and words in verdict.reason
    assert f"{stuck:.2f}" in verdict.reason and verdict.advice
    assert convergence_verdict([10.0, now], now * (1 - MIN_PREDICTED_GAIN) - 0.01, 1.0, clipped=clipped) is None
    # a half step is expected to promise half as much
    assert convergence_verdict([10.0, now], stuck, 1.0, clipped=clipped, share=0.5) is None


def test_a_largest_deviation_that_no_longer_falls_stops_the_plate_even_with_a_good_rms():
    rms, largest = [2.3, 0.69, 0.66], [7.0, 3.4, 3.6]
    assert convergence_verdict(rms, 0.3, 1.0) is None  # the RMS alone still looks like progress
    verdict = convergence_verdict(rms, 0.3, 1.0, max_mm=largest, tolerance_mm=2.5)
    assert verdict is None  # the first correction took most off: not yet a stall
    verdict = convergence_verdict(rms + [0.65], 0.3, 1.0, max_mm=largest + [3.7], tolerance_mm=2.5, share=0.5)
    assert verdict is not None and "largest 3.40 -> 3.60 -> 3.70 mm" in verdict.reason
