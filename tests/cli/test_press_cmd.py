"""``mppf press`` and ``mppf status``'s own helpers: the status lines of a real simulated PLC, the steps to press."""

from __future__ import annotations

import pytest
from mppf.sim.plc.host import run_simulated_plc
from panel_helpers import layout_job

from mppf.cli.plc_ops import connect_session
from mppf.cli.press_cmd import _select_steps, _status_rows
from mppf.core.errors import InputError


def _report(url: str, stop: bool = False) -> dict:
    with connect_session(url, heartbeat_s=None) as plc:
        if stop:
            plc.stop("test")
        return plc.status_report()


def test_the_status_lines_name_every_part_of_the_report_of_an_idle_plc(tmp_path, monkeypatch):
    monkeypatch.setenv("MPPF_HOME", str(tmp_path))
    with run_simulated_plc(watchdog_s=None) as sim:
        report = _report(sim.url)
    rows = dict(_status_rows(report))
    assert list(rows)[:3] == ["matrix", "timing", "state"]
    assert rows["matrix"].startswith(f"{report['rows']} x {report['cols']} punches, map version ")
    assert rows["state"] == "IDLE" and rows["owner"] == "none"
    assert rows["fault"].startswith(f"{report['fault_code']}: ")
    assert rows["status"] == ", ".join(name for name, on in report["status"].items() if on) or "(no bit set)"
    assert {"upper limits", "lower limits"} <= set(rows)
    lo, hi = report["limits_mm"]["upper"]
    assert rows["upper limits"] == f"{lo:.2f}..{hi:.2f} mm"


def test_a_stop_shows_in_the_stops_line_with_the_master_that_sent_it(tmp_path, monkeypatch):
    monkeypatch.setenv("MPPF_HOME", str(tmp_path))
    with run_simulated_plc(watchdog_s=None) as sim:
        report = _report(sim.url, stop=True)
    rows = dict(_status_rows(report))
    assert rows["state"] == "STOPPED"
    assert rows["stops"] == f"1 (last: STOP_REQUEST, master 0x{report['stops']['last_master']:08X})"
    assert report["stops"]["last_master"] != 0


def test_every_step_in_order_or_the_one_asked_for():
    job = layout_job(n_steps=3)
    assert _select_steps(job, None) == [1, 2, 3]
    assert _select_steps(job, 2) == [2]
    for step in (0, 4, -1):
        with pytest.raises(InputError, match=f"--step {step} does not exist: the job has steps 1..3"):
            _select_steps(job, step)
