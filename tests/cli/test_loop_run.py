"""The run of ``mppf loop`` (:mod:`mppf.cli._loop_run`): a new plate drafted, then checked, shown and confirmed
before it is recorded."""

from __future__ import annotations

import io

import numpy as np
import pytest

from mppf.cli._loop_run import SCAN_SIM, RunOptions, draft_plate, run_plate
from mppf.cli._placement import placement_lines
from mppf.core.errors import ConfigError, PressRefused
from mppf.core.progress import NullReporter
from mppf.loop.history import History
from mppf.loop.settings import LoopSettings
from mppf.model.press import example_press_path

PLATE_THICKNESS_MM = 20.0
DRY_RUN = RunOptions(plc_url=None, scanner_spec=SCAN_SIM, time_scale=200.0, scan_timeout_s=60.0)


class Lines(NullReporter):
    """A reporter that keeps the lines it is told (the progress calls do nothing)."""

    def __init__(self):
        self.lines: list[str] = []

    def info(self, message: str) -> None:
        self.lines.append(message)


@pytest.fixture(scope="module")
def draft(plate_files):
    """The loop plate drafted for the example press as ``mppf loop`` drafts a new plate."""
    reporter = Lines()
    made = draft_plate("RUN-1", *plate_files, example_press_path(), PLATE_THICKNESS_MM, LoopSettings(), DRY_RUN,
                       reporter)
    return made, reporter.lines


def test_a_draft_is_the_plate_s_first_cycle_as_the_loop_plans_it(draft, planned_plate):
    """The files read in mm, the press loaded, the first cycle planned: the job the loop's own planner makes."""
    made, lines = draft
    design, flat, press, job = planned_plate
    assert made.plate_id == "RUN-1" and made.press == press and made.press_path == example_press_path()
    assert made.design.n_points == design.n_points and np.allclose(made.flat.points, flat.points)
    assert len(made.job.steps) == len(job.steps) > 0
    for mine, theirs in zip(made.job.steps, job.steps, strict=True):
        assert np.array_equal(mine.active, theirs.active)
        assert np.allclose(mine.upper_mm[mine.active], theirs.upper_mm[theirs.active], atol=1e-9)
    assert lines[0] == "planning plate RUN-1"


def test_a_plate_for_another_press_than_the_installed_one_is_refused_before_the_plc(draft, tmp_path, monkeypatch):
    """At --plc the plate's press must be this machine's: a differing one is refused naming the key, nothing
    recorded and no PLC asked (the URL leads nowhere)."""
    installed = tmp_path / "home"
    installed.mkdir()
    text = example_press_path().read_text()
    assert "max_neighbour_diff_mm = 30.0" in text
    (installed / "press.toml").write_text(text.replace("max_neighbour_diff_mm = 30.0", "max_neighbour_diff_mm = 25.0"))
    monkeypatch.setenv("MPPF_HOME", str(installed))
    recorded = []
    real = RunOptions(plc_url="tcp://127.0.0.1:9?unit=1", scanner_spec=SCAN_SIM, time_scale=1.0, scan_timeout_s=1.0)
    with History(tmp_path / "history.sqlite") as history, pytest.raises(ConfigError) as caught:
        run_plate(history, "RUN-1", draft[0], real, audit=None, reporter=Lines(), record=recorded.append)
    assert "max_neighbour_diff_mm" in str(caught.value) and "--press" in caught.value.hint
    assert recorded == []


def test_a_real_press_without_a_terminal_is_refused_after_the_placement_before_recording(draft, tmp_path,
                                                                                         monkeypatch):
    """The job is checked against the PLC and where to lay the plate is shown; with no terminal to confirm at,
    the press is refused and the drafted plate is not recorded (it can be started again)."""
    from mppf.sim.plc.host import run_simulated_plc

    made, _ = draft
    monkeypatch.setattr("sys.stdin", io.StringIO(""))  # not a terminal
    reporter, recorded = Lines(), []
    with run_simulated_plc(made.press, time_scale=200) as plc, History(tmp_path / "history.sqlite") as history:
        real = RunOptions(plc_url=plc.url, scanner_spec=SCAN_SIM, time_scale=1.0, scan_timeout_s=1.0)
        with pytest.raises(PressRefused) as caught:
            run_plate(history, "RUN-1", made, real, audit=None, reporter=reporter,
                      record=lambda h, d: recorded.append(d))
        assert history.plates() == []
        assert np.allclose(plc.actual_positions_mm()[0], made.press.upper.park_mm)  # nothing moved
    assert "without confirmation" in str(caught.value) and "plate RUN-1" in str(caught.value)
    assert recorded == [] and reporter.lines == placement_lines(made.job)
