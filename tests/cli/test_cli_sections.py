"""Pressing a sectional job section by section (mppf.cli._sections, called by ``mppf press``)."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.cli._sections import SectionRun, press_sections
from mppf.core.errors import InputError, PressRefused
from mppf.core.progress import NULL_REPORTER
from mppf.examples.analytic import cylinder_plate
from mppf.model.plan_options import PlanOptions
from mppf.planning.sectional import plan_plate
from plan_helpers import press  # noqa: F401 (fixture)


class RecordingPress:
    """Stands in for the connected press: records what is checked and pressed."""

    def __init__(self):
        self.checked, self.pressed = [], []

    def check_setpoints(self, upper, lower, active=None):
        self.checked.append((upper.copy(), lower.copy()))

    def run_step(self, upper, lower, reporter=None, timeout_s=None):
        self.pressed.append((upper.copy(), lower.copy()))
        return f"result {len(self.pressed)}"


@pytest.fixture(scope="module")
def job(press):
    design, flat = cylinder_plate(5000.0, 2000.0, 15000.0, spacing_mm=150.0)
    return plan_plate(design, flat, press, 20.0, PlanOptions(steps=2))


def _run(job, plc, lines, shown, **kw):
    placement_lines = kw.pop("placement_lines", None)
    return press_sections(plc, job, SectionRun(job_name="long.job.json", timeout_s=None, **kw),
                          show_result=lambda what, r: shown.append((what, r)), echo=lines.append,
                          make_reporter=lambda: NULL_REPORTER, placement_lines=placement_lines)


def test_dry_run_presses_every_section_in_order_with_its_placement(job):
    plc, lines, shown = RecordingPress(), [], []
    n = _run(job, plc, lines, shown, dry_run=True, yes=False)
    assert len(job.sections) == 2 and n == 4 and len(plc.checked) == 4
    assert [w for w, _ in shown] == ["1 of section 1", "2 of section 1", "1 of section 2", "2 of section 2"]
    expected = [s.steps[k].setpoints_mm(job.press) for s in job.sections for k in range(2)]
    for (up, lo), (eu, el) in zip(plc.pressed, expected):
        assert np.array_equal(up, eu) and np.array_equal(lo, el)
    assert lines[0].startswith("section 1: place the plate with mark 1a over punch row ")
    assert "section 2: place" in lines[1] and "mm along x" in lines[1]


def test_each_section_shows_its_placement_lines(job):
    plc, lines, shown = RecordingPress(), [], []
    corners = lambda one: [f"corner A at x {one.layout.outline_mm[0, 0]:.0f} mm"]  # noqa: E731
    _run(job, plc, lines, shown, dry_run=True, yes=False, placement_lines=corners)
    assert lines[1] == f"corner A at x {job.sections[0].layout.outline_mm[0, 0]:.0f} mm"
    assert lines[3] == f"corner A at x {job.sections[1].layout.outline_mm[0, 0]:.0f} mm" and lines[1] != lines[3]


def test_one_section_and_step_only(job):
    plc, lines, shown = RecordingPress(), [], []
    assert _run(job, plc, lines, shown, dry_run=True, yes=False, section=2, step=1) == 1
    assert np.array_equal(plc.pressed[0][0], job.sections[1].steps[0].setpoints_mm(job.press)[0])
    assert "from section 1" in lines[0]
    with pytest.raises(InputError, match="--section 3 does not exist"):
        _run(job, plc, lines, shown, dry_run=True, yes=False, section=3)


def test_a_real_press_without_a_terminal_is_refused_before_moving(job, monkeypatch):
    plc = RecordingPress()
    plc.identity = None
    monkeypatch.setattr("mppf.cli.press_policy.confirm_motion", lambda link, what, yes: None)
    monkeypatch.setattr("mppf.cli.press_policy.press_description", lambda link: "the press")
    monkeypatch.setattr("sys.stdin.isatty", lambda: False)
    with pytest.raises(PressRefused, match="without confirmation"):
        _run(job, plc, [], [], dry_run=False, yes=False)
    assert plc.pressed == []
    assert _run(job, plc, [], [], dry_run=False, yes=True) == 4


def test_the_plans_border_warnings_are_shown_before_the_sections(job):
    from dataclasses import replace

    assert job.sectional.warnings == ()  # this plan blends within the limit
    warning = "section 2: its strokes step by 5.5 mm at its border with the plate formed before it (limit 1 mm)"
    warned = replace(job, sectional=replace(job.sectional, warnings=(warning,)))
    plc, lines, shown = RecordingPress(), [], []
    assert _run(warned, plc, lines, shown, dry_run=True, yes=False) == 4
    assert lines[0] == f"warning: {warning}" and lines[1].startswith("section 1: place the plate")
