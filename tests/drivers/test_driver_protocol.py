"""Register map v2 through the driver over real TCP sockets: ownership, STOP from anyone, the key
switch, the heartbeat, and scan times from 1 to 200 ms (also over RTU on a pseudo-terminal pair)."""

from __future__ import annotations

import time

import numpy as np
import pytest
from driver_helpers import HookReporter, actions, small_press, step_setpoints

from mppf.core.errors import PressFault, PressRefused
from mppf.drivers.audit import AuditLog
from mppf.drivers.modbus import ModbusPress
from mppf.drivers.modbus_session import ModbusSession
from mppf.sim.plc.host import run_simulated_plc

FAST = 100.0  # simulated seconds per wall second


@pytest.fixture
def press():
    return small_press(3, 4)


@pytest.mark.parametrize("scan_ms", [1, 10, 50, 100, 200])
def test_jobs_complete_at_every_scan_time_over_tcp(press, scan_ms):
    upper, lower = step_setpoints(press)
    with run_simulated_plc(press, time_scale=FAST, scan_s=scan_ms / 1000, watchdog_s=2.0) as sim, \
            ModbusPress(sim.url, press) as plc:
        assert plc.identity.scan_time_s == scan_ms / 1000
        results = [plc.run_step(upper, lower)]
        if scan_ms in (10, 200):  # a COMPLETE job is reset, the next one validated afresh
            results.append(plc.run_step(upper - 3.0, lower + 3.0))
            assert results[1].sequence == results[0].sequence + 1
        assert sim.state() == "COMPLETE"
    assert max(r.max_error_mm for r in results) <= press.position_tolerance_mm


@pytest.mark.rtu
@pytest.mark.parametrize("scan_ms", [1, 10, 50, 100, 200])
def test_jobs_complete_at_every_scan_time_over_rtu(press, scan_ms):
    upper, lower = step_setpoints(press, seed=2)
    with run_simulated_plc(press, rtu=True, baud=115200, time_scale=FAST, scan_s=scan_ms / 1000,
                           watchdog_s=2.0) as sim, \
            ModbusPress(sim.url, press) as plc:
        result = plc.run_step(upper, lower)
        np.testing.assert_allclose(sim.setpoints_mm()[0], upper, atol=1e-9)
    assert result.max_error_mm <= press.position_tolerance_mm


def test_a_second_master_is_refused_before_writing_and_its_stop_is_obeyed(press, tmp_path):
    upper, lower = step_setpoints(press)
    with run_simulated_plc(press, time_scale=20.0, watchdog_s=2.0) as sim, AuditLog(tmp_path / "a.sqlite") as audit, \
            AuditLog(tmp_path / "b.sqlite") as audit_b:
        with ModbusPress(sim.url, press, audit=audit) as owner:
            owner.run_step(upper, lower)  # the owner keeps the PLC between steps
            with ModbusPress(sim.url, press, audit=audit_b) as second:
                with pytest.raises(PressRefused, match=f"owned by master 0x{owner.master_id:08X}.*nothing was written"):
                    second.run_step(upper + 1.0, lower)
                with pytest.raises(PressRefused, match="owned by master"):
                    second.reset()
                report = second.status_report()
            # nothing of the second master reached the PLC: no write in its audit log, the mailbox is the owner's
            assert actions(audit_b) == [("connect", "ok"), ("claim", "not sent"), ("claim", "not sent")]
            assert report["state"] == "COMPLETE" and report["owner_master"] == owner.master_id
            assert report["last_command"]["master"] == owner.master_id
            np.testing.assert_allclose(sim.setpoints_mm()[0], upper, atol=1e-9)

            def stop_from_another_master(task):
                if task.startswith("motion"):
                    time.sleep(0.1)
                    with ModbusSession(sim.url, heartbeat_s=None) as stranger:
                        stranger.stop("the second master's STOP")

            with pytest.raises(PressFault, match="stopped by a STOP request of master 0x") as info:
                owner.run_step(upper + 300.0, lower, reporter=HookReporter(on_start=stop_from_another_master))
            assert "did not complete" in str(info.value)
            assert sim.state() == "STOPPED" and not sim.status_bits()["busy"]
        assert ("complete", "stopped") in actions(audit)


def test_go_is_refused_while_the_key_switch_is_in_local_and_turning_it_stops_the_motion(press):
    upper, lower = step_setpoints(press)
    with run_simulated_plc(press, time_scale=5.0, remote=False, watchdog_s=2.0) as sim, \
            ModbusPress(sim.url, press) as plc:
        with pytest.raises(PressRefused, match="refused GO .*REMOTE_DISABLED.*nothing moved"):
            plc.run_step(upper, lower)
        np.testing.assert_allclose(sim.actual_positions_mm()[0], press.upper.park_mm)
        sim.set_remote(True)
        sim.inject("local", after_s=1.0)
        with pytest.raises(PressFault, match="stopped by the key switch, turned to local"):
            plc.run_step(upper, lower)
        assert sim.state() == "STOPPED"


def test_no_go_without_a_heartbeat_on_a_plc_with_a_watchdog(press):
    upper, lower = step_setpoints(press)
    with run_simulated_plc(press, time_scale=FAST, watchdog_s=1.0) as sim, \
            ModbusPress(sim.url, press, heartbeat_s=None) as plc:
        with pytest.raises(PressRefused, match="GO for job 1 not sent: the heartbeat gap"):
            plc.run_step(upper, lower)
        assert sim.state() == "VALIDATED" and not sim.status_bits()["busy"]


@pytest.mark.usefixtures("steady_gc")
def test_the_heartbeat_is_kept_through_a_step_and_stops_with_the_release(press):
    upper, lower = step_setpoints(press)
    with run_simulated_plc(press, time_scale=20.0, watchdog_s=1.0) as sim:
        with ModbusPress(sim.url, press) as plc:
            assert plc.heartbeat_period_s == pytest.approx(0.1)
            plc.run_step(upper, lower)
            beats = list(sim.plc.beats)
            assert plc.heartbeat_gap_s() <= 1.0 / 4
        gaps = np.diff(beats)
        assert len(beats) > 5 and gaps.max() < 1.0 / 4  # seen by the PLC's scans
        assert not sim.status_bits()["owned"]  # released on close
