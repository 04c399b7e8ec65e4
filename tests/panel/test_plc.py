"""The panel and a simulated PLC in this process: the live reading, lagging punches, link lost, STOP."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from starlette.testclient import TestClient

from driver_helpers import small_press
from panel_helpers import wait_until

from mppf.core.errors import MppfError
from mppf.drivers.audit import AuditLog
from mppf.drivers.modbus import ModbusPress
from mppf.panel.app import STOP_REASON, create_app
from mppf.panel.config import PanelConfig
from mppf.panel.plc import PlcMonitor, status_fields
from mppf.panel.sources import PlcTarget
from mppf.sim.plc.host import run_simulated_plc


@pytest.fixture
def press():
    return small_press()


def _far_setpoints(press):
    """Setpoints 300 mm of travel away from parking (15 s at the press's speed)."""
    return np.full(press.shape, 330.0), np.full(press.shape, -100.0)


class _Driver(threading.Thread):
    """Another master (as 'mppf press' would be) running one long step."""

    def __init__(self, url, press):
        super().__init__(daemon=True)
        self.url, self.press, self.error, self.result = url, press, None, None

    def run(self):
        try:
            with ModbusPress(self.url, self.press) as link:
                self.result = link.run_step(*_far_setpoints(self.press), timeout_s=60)
        except MppfError as exc:
            self.error = exc


def _report(state="IDLE", result="ACCEPTED", **flags):
    """A status report as the driver gives it (register map version 2)."""
    return {"state": state, "status": {"ready": True, "busy": False, "fault": False, "estop": False, **flags},
            "fault_code": 0, "fault_text": "no fault", "owner_master": 0x1A2B,
            "last_command": {"command": "GO", "result": result, "result_text": "refused: not the owner"},
            "validated": {"sequence": 7, "crc": 1}, "motion": {"sequence": 6, "crc": 1},
            "stops": {"count": 2, "last_master": 5, "cause": "REQUEST"}, "plc_heartbeat": 3}


def test_what_the_page_shows_of_a_status_report():
    fields = status_fields(_report())
    assert fields["state"] == "READY" and fields["refusal"] == {"code": 0, "text": "none"}
    assert fields["sequence"] == {"validated": 7, "motion": 6} and fields["owner"] == 0x1A2B
    refused = status_fields(_report("STOPPED", "NOT_OWNER"))
    assert refused["state"] == "STOPPED"
    assert refused["refusal"] == {"code": "NOT_OWNER", "text": "GO: refused: not the owner"}
    assert status_fields(_report("EXECUTING", busy=True))["moving"]


def test_the_monitor_reads_the_press_and_says_when_the_link_is_lost(press):
    with run_simulated_plc(press, time_scale=1.0) as sim:
        monitor = PlcMonitor(lambda: PlcTarget(sim.url, "test"), press).start()
        try:
            snap = wait_until(lambda: monitor.snapshot() if monitor.snapshot()["link"]["ok"] else None, what="a reading")
            assert snap["state"] == "READY"
            assert np.array(snap["matrices"]["upper"]["actual"]).shape == press.shape
            np.testing.assert_allclose(snap["matrices"]["lower"]["actual"], sim.actual_positions_mm()[1], atol=0.01)
            assert monitor.target.url == sim.url
        finally:
            sim.stop()
        try:
            lost = wait_until(lambda: monitor.snapshot() if not monitor.snapshot()["link"]["ok"] else None,
                         what="link lost")
            assert lost["state"] == "LINK LOST" and lost["link"]["url"] == sim.url and lost["link"]["error"]
            assert lost["matrices"] is not None  # the last values stay on the page, marked as old
        finally:
            monitor.close()


def test_a_stuck_punch_is_marked_lagging_while_another_master_drives(press):
    with run_simulated_plc(press, time_scale=2.0) as sim:
        monitor = PlcMonitor(lambda: PlcTarget(sim.url, "test"), press).start()
        driver = _Driver(sim.url, press)
        try:
            wait_until(lambda: monitor.snapshot()["link"]["ok"], what="a reading")
            sim.inject("stuck", matrix="lower", row=2, col=3, percent=10.0)
            driver.start()
            snap = wait_until(lambda: monitor.snapshot() if monitor.snapshot()["n_flagged"] else None, what="a mark")
            names = [f["name"] for f in snap["flagged"]]
            assert names == ["lower R3 C4"], names
            assert snap["moving"] and 0 < snap["progress_pct"] < 100
        finally:
            with ModbusPress(sim.url, None, heartbeat_s=None) as link:
                link.stop("test over")
            driver.join(30)
            monitor.close()


def test_stop_in_the_panel_stops_a_press_driven_by_another_master(press, tmp_path):
    audit_path = tmp_path / "audit.sqlite"
    with run_simulated_plc(press, time_scale=1.0) as sim:
        start = sim.actual_positions_mm()[1].copy()
        cfg = PanelConfig(history_path=tmp_path / "history.sqlite", audit_path=audit_path, plc_url=sim.url,
                          press=press)
        driver = _Driver(sim.url, press)
        with TestClient(create_app(cfg), base_url="http://127.0.0.1:8450") as client:
            driver.start()
            wait_until(lambda: sim.status_bits()["busy"], what="the motion")
            time.sleep(0.5)
            reply = client.post("/stop", headers={"Origin": "http://127.0.0.1:8450"})
            assert reply.status_code == 200 and reply.json()["ok"], reply.text
            wait_until(lambda: not sim.status_bits()["busy"], what="the press to stand still")
            driver.join(30)
        stopped = sim.actual_positions_mm()[1]
    target = _far_setpoints(press)[1]
    assert driver.error is not None and driver.result is None  # the other master saw its step end short
    assert np.all(stopped > start + 1.0) and np.all(stopped < target - 50.0)
    with AuditLog(audit_path) as audit:
        stops = [e for e in audit.entries() if e.action == "stop"]
    assert [(e.outcome, e.detail) for e in stops] == [("ok", STOP_REASON)]


def test_a_panel_started_before_the_first_plate_finds_the_press_later(press):
    found = []
    with run_simulated_plc(press, time_scale=1.0) as sim:
        monitor = PlcMonitor(lambda: PlcTarget(sim.url, "test"), None, find_press=lambda: found[0] if found else None)
        monitor.start()
        try:
            snap = wait_until(lambda: monitor.snapshot() if monitor.snapshot()["link"]["ok"] else None, what="a reading")
            assert snap["matrices"] is None and monitor.press is None  # status only
            found.append(press)  # the first plate is recorded
            snap = wait_until(lambda: monitor.snapshot() if monitor.snapshot()["matrices"] else None, what="the matrices")
            assert monitor.press is press and np.array(snap["matrices"]["upper"]["target"]).shape == press.shape
        finally:
            monitor.close()


def test_no_plc_known_is_not_a_lost_link(press):
    monitor = PlcMonitor(lambda: None, press).start()
    try:
        snap = wait_until(lambda: monitor.snapshot() if "no PLC known" in monitor.snapshot()["link"]["error"] else None,
                     what="the monitor's first look")
        assert snap["state"] == "NO PLC" and snap["link"]["url"] == "" and "--plc" in snap["link"]["error"]
    finally:
        monitor.close()
