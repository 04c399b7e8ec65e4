"""What the panel reads: the PLC of a running master from the audit log, the next cycle, reports."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest

from panel_helpers import layout_job, record_loop

from mppf.drivers.audit import AuditLog
from mppf.panel.sources import HistoryReader, next_cycle, report_files, running_plc


_WRITE_ROW = ("import sys, time; from mppf.drivers.audit import AuditLog; "
              "AuditLog(sys.argv[1]).record(sys.argv[2], 'connect', 'ok'); time.sleep(float(sys.argv[3]))")


def _master(audit_path, url, lives_s: float) -> subprocess.Popen:
    """A process whose command line names mppf (a stand-in for 'mppf loop') that writes one audit row."""
    return subprocess.Popen([sys.executable, "-c", _WRITE_ROW, str(audit_path), url, str(lives_s), "mppf", "loop"])


def _rows(path) -> int:
    with AuditLog(path) as audit:
        return len(audit.entries())


@pytest.fixture
def masters(tmp_path):
    """An ended master (its row first) and a running one, both with their rows in the audit log."""
    path = tmp_path / "audit.sqlite"
    ended = _master(path, "tcp://127.0.0.1:5002?unit=1", 0)
    ended.wait(30)
    running = _master(path, "tcp://127.0.0.1:5001?unit=1", 60)
    deadline = time.monotonic() + 30
    while _rows(path) < 2 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert _rows(path) == 2
    yield path, running
    running.kill()
    running.wait()


def test_the_running_masters_plc_is_found_in_the_audit_log(masters):
    path, running = masters
    found = running_plc(path, own_pid=1)
    assert found.url == "tcp://127.0.0.1:5001?unit=1"
    assert f"pid {running.pid}" in found.source and "mppf loop" in found.source


def test_the_panels_own_rows_and_ended_processes_are_not_a_running_master(masters, tmp_path):
    path, running = masters
    assert running_plc(path, own_pid=running.pid) is None  # the other row's process has ended
    running.kill()
    running.wait()
    assert running_plc(path, own_pid=1) is None
    assert running_plc(tmp_path / "missing.sqlite") is None
    assert not (tmp_path / "missing.sqlite").exists()


def test_the_next_cycle_and_the_current_plate(tmp_path):
    record_loop(tmp_path / "h.sqlite", layout_job(), tmp_path / "work", measured=1).close()
    reader = HistoryReader(tmp_path / "h.sqlite")
    plate, cycles = reader.current()
    assert plate.plate_id == "B12-P3" and [c.state for c in cycles] == ["corrected", "planned"]
    assert next_cycle(cycles).cycle == 2
    assert next_cycle(cycles[:1]).cycle == 1  # none planned: the last one
    assert report_files(plate) == []
    (tmp_path / "work" / "report.html").write_text("<html></html>")
    assert [p.name for p in report_files(plate)] == ["report.html"]
