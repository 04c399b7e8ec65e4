"""Lay the plate, section by section: a job planned in sections shows each section's placement."""

from __future__ import annotations

import re

import pytest
from starlette.testclient import TestClient

from mppf.examples.analytic import cylinder_plate
from mppf.model.plan_options import PlanOptions
from mppf.panel.app import create_app
from mppf.panel.config import PanelConfig
from mppf.planning.job import save_job
from mppf.planning.sectional import plan_plate

LOCAL = "http://127.0.0.1:8450"


class _NoPlc:
    """Stands in for the PLC reader (this view reads no PLC)."""

    target = None

    def __init__(self, press):
        self.press = press

    def start(self):
        pass

    def close(self):
        pass

    def snapshot(self):
        return {"state": "LINK LOST", "link": {"ok": False, "url": "", "error": "test"}}


@pytest.fixture(scope="module")
def sectional_job(tmp_path_factory):
    from mppf.model.press import example_press_path, load_press

    design, flat = cylinder_plate(5000.0, 2000.0, 15000.0, spacing_mm=150.0)
    job = plan_plate(design, flat, load_press(example_press_path()), 20.0, PlanOptions(steps=2))
    return save_job(job, tmp_path_factory.mktemp("sections") / "job.json"), job


def _client(tmp_path, job_path, press):
    config = PanelConfig(history_path=tmp_path / "history.sqlite", audit_path=tmp_path / "audit.sqlite",
                         job_path=job_path)
    return TestClient(create_app(config, monitor=_NoPlc(press)), base_url=LOCAL)


def _corners(text):
    return re.findall(r'data-corner="([A-Z])">\s*<td>[^<]*(?:<span[^>]*>mark</span>)?</td>\s*'
                      r'<td class="num">(-?\d+)</td><td class="num">(-?\d+)</td>', text)


def test_each_section_shows_its_own_placement_and_marks(sectional_job, tmp_path):
    job_path, job = sectional_job
    n = len(job.sections)
    assert n >= 2
    with _client(tmp_path, job_path, job.press) as client:
        first = client.get("/place").text
        second = client.get("/place?section=2").text
        wrong = client.get("/place?section=99").text
    assert f"Section <b>1</b> of {n}" in first and "<b>1a</b>" in first and "<b>1b</b>" in first
    assert f"Section <b>2</b> of {n}" in second and "<b>2a</b>" in second and "moves" in second
    assert 'href="?section=2"' in first and 'href="?section=1"' in second
    # the plate lies elsewhere on the bed in section 2: its corners differ, and the step counts are the section's
    assert _corners(first) and _corners(second) and _corners(first) != _corners(second)
    assert f"of {len(job.sections[1].steps)}: filled circles" in second
    # an unknown section says so and shows section 1
    assert "section &#39;99&#39; does not exist" in wrong and f"Section <b>1</b> of {n}" in wrong
