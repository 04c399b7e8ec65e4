"""The panel's large-type verdict: one for every decision the loop records, each with its colour."""

from __future__ import annotations

import re
from pathlib import Path

from mppf.loop.states import Decision
from mppf.panel import views


def test_every_decision_has_its_own_verdict():
    assert set(views.VERDICTS) == set(Decision)
    assert views.VERDICTS[Decision.NEEDS_REVIEW][0] == "NEEDS REVIEW"
    assert views.VERDICTS[Decision.IN_TOLERANCE][1] == "ok"
    assert all(views.VERDICTS[d][1] == "bad" for d in (Decision.BADLY_FORMED, Decision.CANNOT_CONVERGE,
                                                        Decision.DIVERGED, Decision.MAX_CYCLES))


def test_every_verdict_colour_is_styled():
    css = (Path(views.__file__).parent / "static" / "panel.css").read_text()
    styled = set(re.findall(r"\.verdict\.([a-z]+)\s*\{", css))
    assert {v[1] for v in views.VERDICTS.values()} <= styled
