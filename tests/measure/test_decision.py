"""The one decision rule of an inspection (mppf.measure.decision), as compare and the loop use it."""

from __future__ import annotations

import pytest

from mppf.core.errors import InputError
from mppf.loop.decide import decide
from mppf.loop.settings import LoopSettings
from mppf.loop.states import Decision
from mppf.measure.decision import Figures, Limits, verdict, within_limits

LIMITS = Limits(tolerance_mm=2.5, rms_tolerance_mm=1.0)


def test_in_tolerance_quotes_the_deciding_figures():
    v = verdict(Figures(form_max_mm=1.23, rms_mm=0.41), LIMITS)
    assert v.kind == "in_tolerance" and v.in_tolerance
    assert v.headline.startswith("IN tolerance")
    assert "form max 1.23 mm <= 2.5 mm" in v.headline and "RMS 0.41 mm <= 1 mm" in v.headline


@pytest.mark.parametrize("form, rms, failed", [(5.1, 0.9, "form max 5.10 mm > 2.5 mm"),
                                               (2.0, 1.4, "RMS 1.40 mm > 1 mm")])
def test_out_of_tolerance_on_the_form_max_or_the_rms(form, rms, failed):
    v = verdict(Figures(form, rms), LIMITS)
    assert v.kind == "out_of_tolerance" and not v.in_tolerance
    assert v.reasons == (failed,)
    assert v.headline == f"OUT of tolerance: {failed}"


def test_a_set_aside_point_beyond_the_tolerance_needs_review():
    v = verdict(Figures(1.0, 0.3, set_aside=3, set_aside_beyond=1, set_aside_max_mm=8.2), LIMITS)
    assert v.kind == "needs_review" and not v.in_tolerance
    assert "8.20 mm" in v.headline and "form max 1.00 mm" in v.headline
    # set aside, but all within the tolerance: in tolerance, and said so
    v = verdict(Figures(1.0, 0.3, set_aside=3, set_aside_beyond=0, set_aside_max_mm=2.2), LIMITS)
    assert v.in_tolerance and "3 point(s) set aside, none beyond 2.5 mm" in v.headline
    # the form out of tolerance wins over a review
    assert verdict(Figures(3.0, 0.3, 3, 1, 8.2), LIMITS).kind == "out_of_tolerance"
    assert v.to_dict()["kind"] == "in_tolerance" and v.to_dict()["set_aside"] == 3


def test_the_loop_decides_by_the_same_rule():
    settings = LoopSettings(tolerance_mm=2.5, rms_tolerance_mm=1.0)
    for form, rms in ((1.2, 0.4), (2.6, 0.4), (2.0, 1.2), (2.5, 1.0)):
        in_loop = decide([rms], form, 1, settings) == Decision.IN_TOLERANCE
        assert in_loop == within_limits(form, rms, LIMITS) == verdict(Figures(form, rms), LIMITS).in_tolerance


def test_bad_limits_are_refused():
    with pytest.raises(InputError, match="RMS tolerance"):
        Limits(2.5, 0.0)
