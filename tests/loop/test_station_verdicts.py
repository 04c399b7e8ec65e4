"""An outside scanner station that scans a badly formed plate, or writes the scan in other units (issue 20.5).

The loop runs in-process (the in-process press, the folder scanner); the station is another
process (tests/scan_station.py ``--bend`` / ``--scale``).
"""

from __future__ import annotations

import pytest
from driver_helpers import HookReporter
from station_helpers import asymmetric_points, planned_plate, start_station, station_log

from mppf.core.errors import MppfError
from mppf.drivers.audit import AuditLog
from mppf.loop.cycle import run_loop
from mppf.loop.history import History
from mppf.loop.options import LoopOptions, PlateInputs
from mppf.loop.plate import record_plate
from mppf.loop.scanners import DirectoryScanner
from mppf.loop.settings import LoopSettings
from mppf.sim.plc.link import InProcessPress

SETTINGS = dict(max_cycles=2, margin_mm=0.0, mark_settle_s=1.0, mark_timeout_s=8.0)


@pytest.fixture(scope="module")
def bump(tmp_path_factory):
    """The asymmetric plate (1400 x 900 mm, a 60 mm bump), planned: (design, flat, press, job)."""
    return planned_plate(tmp_path_factory.mktemp("bump"), "bump", asymmetric_points(), LoopSettings(**SETTINGS))


def _run(tmp_path, plate, **station):
    design, flat, press, job = plate
    folder = tmp_path / "scans"
    folder.mkdir()
    history = History(tmp_path / "h.sqlite")
    record_plate(history, PlateInputs(design, flat, press, 20.0), job, plate_id="V1", work_dir=tmp_path / "V1",
                 options=LoopOptions(settings=LoopSettings(**SETTINGS)))
    process = start_station(folder, design.path, "early", **station)
    reporter = HookReporter()
    with AuditLog(tmp_path / "audit.sqlite") as audit, InProcessPress(press, audit=audit) as link:
        try:
            outcome = run_loop(history, "V1", link, DirectoryScanner(folder, timeout_s=6.0, poll_s=0.2),
                               reporter=reporter)
        except MppfError as exc:
            outcome = exc
    lines = station_log(process)
    return outcome, reporter.messages, lines, history


def test_a_badly_formed_plate_from_the_station_stops_the_loop_with_its_verdict(bump, tmp_path):
    result, messages, lines, history = _run(tmp_path, bump, bend=3.0)
    with history:
        record = history.cycle("V1", 1)
        assert result.status == "badly_formed", messages
        assert record.decision == "badly_formed" and record.state == "done"
        assert "badly formed" in record.comparison["verdict"]["headline"] if "verdict" in record.comparison \
            else any("badly formed" in m for m in messages)
        assert len(history.cycles("V1")) == 1  # no correction planned from it
    assert [line.split()[0] for line in lines] == ["request", "mark", "scan", "gone"]


def test_a_scan_in_metres_is_refused_as_another_plate_and_the_cycle_waits(bump, tmp_path):
    outcome, messages, lines, history = _run(tmp_path, bump, scale=0.001)
    with history:
        record = history.cycle("V1", 1)
        assert isinstance(outcome, MppfError) and outcome.exit_code == 2, outcome
        assert record.state == "pressed" and record.decision is None  # not compared: --resume takes another scan
        rejected = " ".join(r.get("reason", "") for r in record.rejected_scans)
        assert "units" in rejected, rejected
    assert lines[0].startswith("request") and "scan" in [line.split()[0] for line in lines]
