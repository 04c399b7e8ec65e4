"""The Modbus press driver over Modbus RTU on a real pseudo-terminal pair."""

from __future__ import annotations

import time

import numpy as np
import pytest
from driver_helpers import HookReporter, small_press, step_setpoints

from mppf.drivers.audit import AuditLog
from mppf.drivers.modbus import ModbusPress
from mppf.drivers.url import parse_plc_url
from mppf.core.errors import PressFault
from mppf.sim.plc.host import run_simulated_plc

pytestmark = pytest.mark.rtu


@pytest.mark.parametrize("word_order", ["ABCD", "CDAB"])
def test_upload_verify_go_complete_over_rtu(tmp_path, word_order):
    press = small_press()
    upper, lower = step_setpoints(press, seed=3)
    with run_simulated_plc(press, rtu=True, baud=115200, word_order=word_order, time_scale=50.0) as sim:
        url = parse_plc_url(sim.url)
        assert url.scheme == "rtu" and url.device == sim.serial_port
        with AuditLog(tmp_path / "a.sqlite") as audit, ModbusPress(sim.url, press, audit=audit) as plc:
            assert plc.identity.word_order == word_order
            result = plc.run_step(upper, lower)
            assert [e.action for e in audit.entries()][-4:] == ["upload", "validate", "go", "complete"]
        np.testing.assert_allclose(sim.setpoints_mm()[0], upper, atol=1e-9)
    np.testing.assert_allclose(result.actual_lower_mm, lower, atol=press.position_tolerance_mm)


@pytest.mark.usefixtures("steady_gc")
def test_heartbeat_goes_on_during_a_long_paced_upload():
    """At 115200 baud a 16 x 24 upload and read-back take about 0.8 s: the heartbeat frames slip
    in between the setpoint frames (urgent requests go first), so the gap between two beats
    stays far below the upload's length and within a quarter of the watchdog (else the driver
    would refuse GO); the owner's lease holds and the motion is not stopped by the watchdog."""
    press = small_press(16, 24)
    upper, lower = step_setpoints(press)
    seen = {}
    with run_simulated_plc(press, rtu=True, baud=115200, paced=True, time_scale=200.0, watchdog_s=1.0) as sim:
        with ModbusPress(sim.url, press, heartbeat_s=0.05, timeout_s=2.0) as plc:

            def upload_started(task):
                if task.startswith("upload"):
                    seen["start"] = time.monotonic()
                elif task.startswith("motion"):
                    seen["lease_at_go"] = sim.status_bits()["lease_ok"]

            def verified(message):
                if "written and verified" in message:
                    seen["upload_s"], seen["gap_s"] = time.monotonic() - seen["start"], plc.heartbeat_gap_s()

            result = plc.run_step(upper, lower, reporter=HookReporter(on_start=upload_started, on_info=verified))
    assert seen["lease_at_go"] and result.max_error_mm <= press.position_tolerance_mm
    assert seen["upload_s"] > 0.6 and seen["gap_s"] < min(0.25, seen["upload_s"] / 3)


def test_stuck_punch_over_rtu():
    press = small_press()
    upper, lower = step_setpoints(press)
    with run_simulated_plc(press, rtu=True, time_scale=50.0) as sim:
        sim.inject("stuck", matrix="upper", row=3, col=0, percent=20)
        with ModbusPress(sim.url, press) as plc, pytest.raises(PressFault, match=r"upper punch \(row 4, col 1\)"):
            plc.run_step(upper, lower)


def test_exception_reply_over_rtu_is_a_plc_error():
    """A write beyond the register map is answered with a Modbus exception frame (5 bytes; the
    only exception the PLC sends), which the exact-length RTU reader must decode into
    PlcError, not a timeout."""
    from mppf.drivers.modbus_adapter import ModbusAdapter
    from mppf.drivers.regmap import load_register_map
    from mppf.core.errors import PlcError

    rmap = load_register_map()
    with run_simulated_plc(small_press(), rtu=True, time_scale=50.0) as sim:
        with ModbusAdapter(parse_plc_url(sim.url)) as link:
            with pytest.raises(PlcError, match="exception 2"):
                link.write_registers(rmap.total_registers - 1, [1, 2], retries=0)
            # the link is still in step: the next request gets its own answer
            assert link.read_holding(rmap["map_version"].address, 1) == [rmap.version]


def test_silent_rtu_line_is_a_link_error_within_the_timeout():
    """Nothing answers on the other end of the pty: a read fails with LinkError after the
    reply timeout (and its retries), not later and not with a hang."""
    import time

    from mppf.drivers.modbus_adapter import ModbusAdapter
    from mppf.core.errors import LinkError
    from mppf.sim.serial_pty import PtyPair

    pair = PtyPair()
    try:
        url = parse_plc_url(f"rtu://{pair.port_b}?baud=115200&parity=N&unit=1&timeout=0.2&retries=1")
        with ModbusAdapter(url) as link:
            start = time.monotonic()
            with pytest.raises(LinkError):
                link.read_holding(0, 2)
            elapsed = time.monotonic() - start
    finally:
        pair.close()
    assert 0.35 <= elapsed < 2.0  # two attempts of 0.2 s each, plus the pause between them
