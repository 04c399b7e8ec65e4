"""Why a verdict needs review: set-aside points beyond the tolerance, areas not measured, or both."""

from __future__ import annotations

from mppf.measure.decision import REVIEW_ARTEFACTS, REVIEW_UNCOVERED, Figures, Limits, verdict


def test_review_causes_tell_an_area_not_measured_from_the_rest():
    limits = Limits(2.5, 1.0)
    gaps = dict(gaps=("0.2 m^2 at u, v = 0, 0 mm",), n_gaps=1, allowed_gap_mm=100.0)
    only_gaps = verdict(Figures(1.0, 0.4, **gaps), limits)
    assert only_gaps.kind == "needs_review" and only_gaps.review_causes == (REVIEW_UNCOVERED,) and only_gaps.only_uncovered
    both = verdict(Figures(1.0, 0.4, set_aside=5, set_aside_beyond=2, set_aside_max_mm=4.0, **gaps), limits)
    assert both.review_causes == (REVIEW_ARTEFACTS, REVIEW_UNCOVERED) and not both.only_uncovered
    artefacts = verdict(Figures(1.0, 0.4, set_aside=5, set_aside_beyond=2, set_aside_max_mm=4.0), limits)
    assert artefacts.review_causes == (REVIEW_ARTEFACTS,) and not artefacts.only_uncovered
    # out of tolerance or in tolerance: nothing to review, whatever was not measured
    out = verdict(Figures(3.0, 0.4, **gaps), limits)
    assert out.kind == "out_of_tolerance" and out.review_causes == () and not out.only_uncovered
    passed = verdict(Figures(1.0, 0.4, allowed_gap_mm=100.0), limits)
    assert passed.in_tolerance and passed.review_causes == () and not passed.only_uncovered
