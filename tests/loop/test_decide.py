"""The decision after a compared cycle."""

from __future__ import annotations

from mppf.loop.decide import decide
from mppf.loop.settings import LoopSettings
from mppf.loop.states import Decision


def test_decide_in_tolerance_needs_both_limits():
    s = LoopSettings(tolerance_mm=2.5, rms_tolerance_mm=1.0, max_cycles=5)
    assert decide([0.9], 2.4, 1, s) == "in_tolerance"
    assert decide([1.1], 2.4, 1, s) == "continue"  # RMS too large
    assert decide([0.9], 2.6, 1, s) == "continue"  # one place too far off


def test_decide_divergence_and_max_cycles():
    s = LoopSettings(max_cycles=4, divergence_factor=1.5)
    assert decide([2.0, 3.1], 9.0, 2, s) == "continue"  # grew by more than 1.5x: a half step from the best follows
    assert decide([2.0, 3.1, 3.05], 9.0, 3, s) == "diverged"  # ... and did not recover
    assert decide([2.0, 3.1, 2.9], 9.0, 3, s) == "continue"  # it recovered below 1.5x the best
    assert decide([2.0, 2.9], 9.0, 2, s) == "continue"
    assert decide([1.5, 1.7, 1.9], 9.0, 3, s) == "diverged"  # grew twice in a row
    assert decide([1.5, 1.55, 1.6], 9.0, 3, s) == "continue"  # within the noise margin
    assert decide([3.0, 2.0, 1.5, 1.2], 3.0, 4, s) == "max_cycles"


def test_decisions_are_their_stored_text():
    decision = decide([0.5], 1.0, 1, LoopSettings())
    assert decision is Decision.IN_TOLERANCE and decision == "in_tolerance" and f"{decision}" == "in_tolerance"


def test_set_aside_points_beyond_the_tolerance_stop_the_loop_for_review_never_in_tolerance():
    settings = LoopSettings(tolerance_mm=2.5, rms_tolerance_mm=1.0)
    assert decide([0.6], 2.0, 1, settings, set_aside_beyond=3) == Decision.NEEDS_REVIEW
    assert decide([0.6], 2.0, 1, settings, set_aside_beyond=0) == Decision.IN_TOLERANCE
    # out of tolerance anyway: the loop goes on correcting (the artefacts do not decide)
    assert decide([1.6], 4.0, 1, settings, set_aside_beyond=3) == Decision.CONTINUE
