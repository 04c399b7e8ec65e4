"""Every ending of the loop with its verdict: why, where, what to do, and the exit code (mppf/loop/endings.py)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from mppf.correct.verdict import Verdict
from mppf.loop.endings import ending, exit_code
from mppf.loop.settings import LoopSettings
from mppf.loop.states import Decision


def _cycle(number, form_max_mm, rms_mm, reasons=()):
    comparison = {"form": {"peak_mm": -form_max_mm, "peak_uv_mm": [1480.0, -990.0]},
                  "verdict": {"reasons": list(reasons)}}
    return SimpleNamespace(cycle=number, max_abs_mm=form_max_mm, rms_mm=rms_mm, comparison=comparison)


@pytest.mark.parametrize("decision, code", [
    (Decision.IN_TOLERANCE, 0), (Decision.NEEDS_REVIEW, 6), (Decision.CANNOT_CONVERGE, 5), (Decision.DIVERGED, 5),
    (Decision.MAX_CYCLES, 5), (Decision.BADLY_FORMED, 5)])
def test_every_ending_has_a_reason_a_region_advice_and_its_exit_code(decision, code):
    cycles = [_cycle(1, 24.0, 8.0), _cycle(2, 2.3, 0.6, ["2 point(s) set aside lie beyond 2.5 mm"]),
              _cycle(3, 4.1, 1.2)]
    end = ending(decision, cycles, LoopSettings())
    assert end.exit_code == code == exit_code(decision)
    assert end.why and end.advice and "cycle 3: form max 4.10 mm, RMS 1.20 mm" in end.why
    assert end.region == "largest form deviation -4.10 mm at design u, v = 1480, -990 mm"
    doc = end.to_dict()
    assert doc["decision"] == str(decision) and doc["exit_code"] == code and doc["text"] == end.text
    assert end.text.startswith(str(decision).replace("_", " ")) and "what to do:" in end.text
    if decision in (Decision.DIVERGED, Decision.MAX_CYCLES, Decision.CANNOT_CONVERGE):
        assert "the best was cycle 2: form max 2.30 mm" in end.why  # the operator sees what was reached


def test_a_divergence_names_the_rms_growth_and_a_review_its_reasons():
    cycles = [_cycle(1, 20.0, 6.0), _cycle(2, 2.0, 0.5), _cycle(3, 9.0, 2.5)]
    assert "RMS deviation grew (6.00 -> 0.50 -> 2.50 mm" in ending(Decision.DIVERGED, cycles, LoopSettings()).why
    review = ending(Decision.NEEDS_REVIEW, [_cycle(1, 2.0, 0.5, ["3 spots not measured"])], LoopSettings())
    assert "3 spots not measured" in review.why and "rescan" in review.advice


def test_the_correction_s_verdict_gives_its_reason_and_advice():
    verdict = Verdict("the strokes it needs lie beyond the stroke limits at 4 punches", "re-plan the layout")
    end = ending(Decision.CANNOT_CONVERGE, [_cycle(1, 20.0, 6.0), _cycle(2, 5.0, 1.5)], LoopSettings(), verdict)
    assert verdict.reason in end.why and end.advice == "re-plan the layout" and end.exit_code == 5


def test_an_unmeasured_plate_still_ends_with_a_verdict():
    end = ending(Decision.MAX_CYCLES, [SimpleNamespace(cycle=1, max_abs_mm=None, rms_mm=None, comparison=None)],
                 LoopSettings())
    assert end.why == "no cycle was measured" and end.region == "" and end.exit_code == 5
