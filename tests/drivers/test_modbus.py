"""The Modbus press driver against the simulated PLC over real TCP sockets.

No mocks: every test starts the simulated PLC (a pymodbus server on a loopback port)
and talks Modbus to it. Faults are injected in the simulator at precise moments of a
step through a :class:`HookReporter`.
"""

from __future__ import annotations

import asyncio
import threading
import time

import numpy as np
import pytest
from driver_helpers import HookReporter, actions, open_audit, small_press, step_setpoints

from mppf.drivers.modbus import ModbusPress, motion_time_s
from mppf.drivers.modbus_adapter import ModbusAdapter
from mppf.drivers.regmap import load_register_map
from mppf.drivers.url import parse_plc_url
from mppf.core.errors import Cancelled, ConfigError, InputError, LimitError, LinkError, PressFault, PressRefused
from mppf.sim.plc.host import start_simulated_plc

FAST = 50.0  # simulated seconds per wall second for ordinary steps


@pytest.fixture
def press():
    return small_press()


@pytest.fixture
def start_sim(press):
    """Start simulated PLCs (TCP on a free loopback port); all stopped at the end."""
    handles = []

    def start(**options):
        options.setdefault("time_scale", FAST)
        options.setdefault("watchdog_s", 2.0)  # margin for a loaded test machine: a beat every 0.2 s, GO if <= 0.5 s
        handle = start_simulated_plc(options.pop("press", press), **options)
        handles.append(handle)
        return handle

    yield start
    for handle in handles:
        handle.stop()


audit = pytest.fixture(open_audit, name="audit")


@pytest.mark.parametrize("word_order", ["ABCD", "CDAB"])
def test_upload_verify_go_complete(start_sim, press, audit, word_order):
    sim = start_sim(word_order=word_order)
    upper, lower = step_setpoints(press)
    lower = lower - 35.0  # negative values exercise the sign of the int32 encoding
    reporter = HookReporter()
    with ModbusPress(sim.url, press, audit=audit, job_sha256="f" * 64) as plc:
        assert plc.identity.word_order == word_order
        assert (plc.identity.rows, plc.identity.cols) == press.shape
        first = plc.run_step(upper, lower, reporter=reporter)
        second = plc.run_step(upper - 5.0, lower + 5.0)
    # the PLC holds exactly the setpoints and the punches stand on them
    sim_upper, sim_lower = sim.setpoints_mm()
    np.testing.assert_allclose(sim_upper, upper - 5.0, atol=1e-9)
    np.testing.assert_allclose(sim_lower, lower + 5.0, atol=1e-9)
    act_upper, act_lower = sim.actual_positions_mm()
    np.testing.assert_allclose(act_upper, upper - 5.0, atol=press.position_tolerance_mm)
    np.testing.assert_allclose(second.actual_upper_mm, act_upper, atol=0.005)
    np.testing.assert_allclose(first.target_upper_mm, upper, atol=1e-9)
    assert first.max_error_mm <= press.position_tolerance_mm
    assert second.sequence == first.sequence + 1  # a new sequence per upload
    # the motion took about as long as the hydraulics need at the time scale
    travel = max(np.abs(upper - press.upper.park_mm).max(), np.abs(lower - press.lower.park_mm).max())
    expected_s = motion_time_s(travel, press.speed_mm_s, press.accel_mm_s2) / FAST
    assert expected_s * 0.8 < first.duration_s < expected_s + 0.5
    # progress: upload, then motion
    assert reporter.tasks[0].startswith("upload") and reporter.tasks[1].startswith("motion")
    assert any("verified" in m for m in reporter.messages)
    # the audit log has the handshake in order, with sequence and job hash, every row written ahead
    steps = [a for a in actions(audit) if a[0] != "connect"]
    one_step = [("upload", "ok"), ("upload", "ok"), ("validate", "ok"), ("go", "ok"), ("complete", "ok")]
    assert steps == [("claim", "ok"), *one_step, ("reset", "ok"), *one_step, ("release", "ok")]
    assert all(e.outcome_time_s >= e.time_s for e in audit.entries())
    rows = [e for e in audit.entries() if e.action == "go"]
    assert [e.sequence for e in rows] == [first.sequence, second.sequence]
    assert all(e.job_sha256 == "f" * 64 and e.plc == str(parse_plc_url(sim.url)) for e in rows)


def test_strokes_beyond_limits_are_refused_before_any_write(start_sim, press, audit):
    sim = start_sim()
    upper, lower = step_setpoints(press)
    upper[1, 2] = press.upper.max_mm + 10.0
    lower[3, 5] = press.lower.min_mm - 1.0
    before = sim.setpoints_mm()
    with ModbusPress(sim.url, press, audit=audit) as plc:
        status_before = plc.status_report()
        with pytest.raises(LimitError) as info:
            plc.run_step(upper, lower)
        status_after = plc.status_report()
    message = str(info.value)
    assert "2 setpoint(s) beyond" in message and "nothing was written" in message
    assert "upper punch (row 2, col 3)" in message and f"{press.upper.max_mm + 10.0:.2f}" in message
    assert "lower punch (row 4, col 6)" in message and "limits -400.00..300.00 mm" in message
    # nothing reached the PLC: setpoints, owner, jobs, mailbox untouched
    after = sim.setpoints_mm()
    for a, b in zip(before, after):
        np.testing.assert_array_equal(a, b)
    for key in ("state", "owner_master", "validated", "motion", "last_command", "last_sequence"):
        assert status_after[key] == status_before[key]
    assert sim.server.master_writes == 0
    assert ("upload", "ok") not in actions(audit)
    assert ("limits", "refused") in actions(audit)


def test_a_plc_limit_tighter_than_the_press_description_is_checked_too(start_sim, press):
    doc = press.to_dict()
    doc["upper"]["max_mm"] = 100.0
    doc["upper"]["park_mm"] = 100.0
    from mppf.model.press import press_from_dict

    sim = start_sim(press=press_from_dict(doc))
    upper, lower = step_setpoints(press, upper_mm=95.0)  # up to 115 mm: fine for the press file
    with ModbusPress(sim.url, press) as plc, pytest.raises(LimitError, match="limits -300.00..100.00"):
        plc.run_step(upper, lower)


def test_bad_setpoint_arrays_are_input_errors(start_sim, press):
    sim = start_sim()
    upper, lower = step_setpoints(press)
    with ModbusPress(sim.url, press) as plc:
        with pytest.raises(InputError, match="shape"):
            plc.run_step(upper[:2], lower)
        with pytest.raises(InputError, match="must be numbers .* got an array of bool"):
            plc.run_step(np.ones(press.shape, bool), lower)
        upper[0, 1] = np.nan
        with pytest.raises(InputError, match="NaN"):
            plc.run_step(upper, lower)
    assert sim.server.master_writes == 0


def test_link_dropped_mid_upload_no_go_then_a_retry_works(start_sim, press, audit):
    sim = start_sim(watchdog_s=None)
    upper, lower = step_setpoints(press)
    with ModbusPress(sim.url, press, audit=audit, heartbeat_s=None, timeout_s=0.5) as plc:
        sim.inject("drop", after_writes=2, duration_s=1.5)  # write 1 is the CLAIM: the first setpoint frame is lost
        with pytest.raises(LinkError) as info:
            plc.run_step(upper, lower)
        assert "before GO" in str(info.value) and "GO was not sent, so this job never started" in str(info.value)
        flags = sim.status_bits()
        assert not flags["busy"] and sim.state() != "VALIDATED"
        assert ("go", "ok") not in actions(audit) and ("upload", "failed") in actions(audit)
        time.sleep(1.6)  # the link comes back
        result = plc.run_step(upper, lower)
    assert result.max_error_mm <= press.position_tolerance_mm
    assert actions(audit)[-3:] == [("go", "ok"), ("complete", "ok"), ("release", "ok")]


def test_plc_restart_during_motion_is_detected(start_sim, press, audit):
    sim = start_sim(time_scale=5.0)
    upper, lower = step_setpoints(press)

    def restart(task):
        if task.startswith("motion"):
            sim.restart(downtime_s=0.3)

    with ModbusPress(sim.url, press, audit=audit) as plc:
        with pytest.raises((LinkError, PressFault)) as info:
            plc.run_step(upper, lower, reporter=HookReporter(on_start=restart))
        assert "restarted" in str(info.value)
        st = plc.status()
    assert not st.busy and st.motion_sequence == 0
    assert ("stop", "ok") in actions(audit)


def test_link_lost_during_motion_stop_after_reconnect(start_sim, press, audit):
    sim = start_sim(time_scale=5.0, watchdog_s=None)
    upper, lower = step_setpoints(press)

    def drop(task):
        if task.startswith("motion"):
            sim.drop_connections(0.4)

    with ModbusPress(sim.url, press, audit=audit, timeout_s=0.3) as plc:
        with pytest.raises(LinkError) as info:
            plc.run_step(upper, lower, reporter=HookReporter(on_start=drop))
    message = str(info.value)
    assert "after GO" in message and "STOP was sent after reconnecting" in message
    assert "restarted" not in message
    assert [e.detail.startswith("link lost") for e in audit.entries() if e.action == "stop"] == [True]
    flags = sim.wait_idle(3.0)
    assert not flags["busy"] and not flags["in_position"]  # stopped short of the targets


def test_estop_during_motion_stops_and_reports(start_sim, press, audit):
    sim = start_sim(time_scale=50.0)
    upper, lower = step_setpoints(press)
    sim.inject("estop", after_s=2.0)  # 2 simulated s into the motion
    with ModbusPress(sim.url, press, audit=audit) as plc:
        with pytest.raises(PressFault) as info:
            plc.run_step(upper, lower)
        assert "ESTOP" in str(info.value) and "STOP was sent" in str(info.value)
        assert ("stop", "ok") in actions(audit)
        assert not sim.wait_idle(2.0)["busy"]
        # latched: a new step is refused until the cause is gone and RESET is sent
        with pytest.raises(PressRefused, match="e-stop"):
            plc.run_step(upper, lower)
        with pytest.raises(PressRefused, match="ESTOP_ACTIVE"):
            plc.reset()
        sim.release_estop()
        assert plc.status().fault  # still latched: reset only on request
        plc.reset()
        assert plc.status().ready
        result = plc.run_step(upper, lower)
    assert result.max_error_mm <= press.position_tolerance_mm


def test_an_estop_at_the_start_of_motion_is_named_not_reported_as_a_foreign_job(start_sim, press, audit):
    """A PLC may fault between GO and the first status read (scan latency): the fault is what the operator sees."""
    sim = start_sim(time_scale=50.0)
    upper, lower = step_setpoints(press)
    sim.inject("estop", after_s=0.0)  # at once when the motion starts
    with ModbusPress(sim.url, press, audit=audit) as plc:
        with pytest.raises(PressFault) as info:
            plc.run_step(upper, lower)
    message = str(info.value)
    assert "ESTOP" in message and "STOP was sent" in message and "not our job" not in message
    assert ("stop", "ok") in actions(audit)


def test_stuck_punch_is_named_from_the_actual_positions(start_sim, press):
    sim = start_sim()
    upper, lower = step_setpoints(press)
    sim.inject("stuck", matrix="lower", row=2, col=4, percent=50)
    with ModbusPress(sim.url, press) as plc, pytest.raises(PressFault) as info:
        plc.run_step(upper, lower)
    message = str(info.value)
    assert "STUCK_PUNCH" in message  # out of its band: never COMPLETE, the positioning timeout latches it
    assert f"lower punch (row 3, col 5) target {lower[2, 4]:.2f} mm" in message
    actual = sim.actual_positions_mm()[1][2, 4]
    assert f"actual {actual:.2f} mm" in message


def test_stuck_punch_fault_of_the_plc_names_the_punch(start_sim, press):
    sim = start_sim()
    upper, lower = step_setpoints(press)
    sim.inject("stuck", matrix="upper", row=0, col=1, percent=30, fault_after_s=0.5)
    with ModbusPress(sim.url, press) as plc, pytest.raises(PressFault) as info:
        plc.run_step(upper, lower)
    assert "STUCK_PUNCH" in str(info.value) and "upper punch (row 1, col 2)" in str(info.value)


def test_a_halted_plc_program_is_detected_from_its_stale_heartbeat(start_sim, press, audit):
    sim = start_sim(time_scale=5.0)
    upper, lower = step_setpoints(press)
    sim.inject("freeze", after_s=1.0)  # the PLC program halts 1 s into the motion; the link still answers
    t0 = time.monotonic()
    with ModbusPress(sim.url, press, audit=audit) as plc, pytest.raises(PressFault) as info:
        plc.run_step(upper, lower)
    assert time.monotonic() - t0 < 5.0  # long before the motion timeout (about 45 s here)
    assert "the PLC heartbeat stayed at" in str(info.value) and "PLC program is not running" in str(info.value)
    assert "stop the press at the machine" in info.value.hint
    assert ("stop", "ok") in actions(audit) and ("complete", "ok") not in actions(audit)


def test_watchdog_expiry_when_the_heartbeat_stops(start_sim, press, audit):
    sim = start_sim(time_scale=5.0, watchdog_s=1.0)
    upper, lower = step_setpoints(press)
    with ModbusPress(sim.url, press, audit=audit, heartbeat_s=0.1) as plc:
        hook = HookReporter(on_start=lambda task: task.startswith("motion") and plc.stop_heartbeat())
        with pytest.raises(PressFault, match="WATCHDOG"):
            plc.run_step(upper, lower, reporter=hook)
        assert not sim.wait_idle(2.0)["busy"]
        plc.start_heartbeat()
        plc.reset()
        assert not plc.status().fault


def test_foreign_write_between_verification_and_go_is_refused(start_sim, press, audit):
    sim = start_sim()
    upper, lower = step_setpoints(press)

    def foreign(message):
        if "validated by the PLC" in message:
            sim.write_foreign_setpoint("upper", 1, 1, 55.5)

    before = sim.actual_positions_mm()
    with ModbusPress(sim.url, press, audit=audit) as plc:
        with pytest.raises(PressRefused) as info:
            plc.run_step(upper, lower, reporter=HookReporter(on_info=foreign))
        st = plc.status_report()
    assert "refused GO" in str(info.value) and "WRONG_STATE" in str(info.value)
    assert "the setpoints changed after validation" in str(info.value) and "nothing moved" in str(info.value)
    assert st["motion"]["sequence"] == 0 and not st["status"]["busy"] and st["state"] == "LOADED"
    for a, b in zip(before, sim.actual_positions_mm()):
        np.testing.assert_array_equal(a, b)
    assert ("go", "refused") in actions(audit)


def test_foreign_write_during_upload_fails_verification_or_validation(start_sim, press, audit):
    sim = start_sim()
    upper, lower = step_setpoints(press)

    def foreign(task):
        if task.startswith("upload"):
            sim.write_foreign_setpoint("lower", 3, 5, -1.0)

    # the foreign value lands before our frames and is overwritten: the step succeeds
    with ModbusPress(sim.url, press, audit=audit) as plc:
        plc.run_step(upper, lower, reporter=HookReporter(on_start=foreign))

        def foreign_after(message):
            if "written and verified" in message:
                sim.write_foreign_setpoint("lower", 3, 5, -1.0)

        with pytest.raises(PressRefused, match="refused job .* CRC_MISMATCH"):
            plc.run_step(upper + 1, lower, reporter=HookReporter(on_info=foreign_after))
    assert ("validate", "refused") in actions(audit)


def test_timeout_sends_stop(start_sim, press, audit):
    sim = start_sim(time_scale=1.0)
    upper, lower = step_setpoints(press)
    with ModbusPress(sim.url, press, audit=audit) as plc, pytest.raises(PressFault, match="did not end within 0.3 s"):
        plc.run_step(upper, lower, timeout_s=0.3)
    assert ("stop", "ok") in actions(audit)
    assert not sim.wait_idle(5.0)["busy"]


def test_ctrl_c_during_motion_sends_stop_and_cancels(start_sim, press, audit):
    sim = start_sim(time_scale=2.0)
    upper, lower = step_setpoints(press)

    def operator_presses_ctrl_c(completed):
        raise KeyboardInterrupt

    with ModbusPress(sim.url, press, audit=audit) as plc, pytest.raises(Cancelled, match="STOP was sent"):
        plc.run_step(upper, lower, reporter=HookReporter(on_update=operator_presses_ctrl_c))
    assert [e.detail for e in audit.entries() if e.action == "stop"] == ["cancelled by the operator"]
    flags = sim.wait_idle(5.0)
    assert not flags["busy"] and not flags["in_position"]  # stopped short of the targets


def test_ctrl_c_again_while_stop_is_sent_repeats_the_stop(start_sim, press, audit):
    sim = start_sim(time_scale=2.0, watchdog_s=None)  # no watchdog: only a STOP ends the motion
    upper, lower = step_setpoints(press)
    rmap = load_register_map()
    interrupted = []

    def operator_presses_ctrl_c(completed):
        raise KeyboardInterrupt

    with ModbusPress(sim.url, press, audit=audit) as plc:
        send = plc._io.write_command

        def write_command(address, words, urgent=False):
            if address == rmap["stop_request"].address and not interrupted:
                interrupted.append(words)
                raise KeyboardInterrupt  # the operator's second Ctrl-C, before the STOP frame left
            return send(address, words, urgent=urgent)

        plc._io.write_command = write_command
        with pytest.raises(Cancelled, match="STOP was sent"):
            plc.run_step(upper, lower, reporter=HookReporter(on_update=operator_presses_ctrl_c))
    assert interrupted
    assert [(e.outcome, e.detail) for e in audit.entries() if e.action == "stop"] == [
        ("interrupted", "cancelled by the operator"),  # its intent was written ahead, then Ctrl-C came
        ("ok", "cancelled by the operator (Ctrl-C again: STOP repeated)")]
    flags = sim.wait_idle(5.0)
    assert not flags["busy"] and not flags["in_position"]


def test_an_unexpected_error_after_go_sends_stop(start_sim, press, audit):
    sim = start_sim(time_scale=2.0, watchdog_s=None)  # no watchdog: only a STOP ends the motion
    upper, lower = step_setpoints(press)

    def display_breaks(completed):
        raise RuntimeError("the progress display broke")

    with ModbusPress(sim.url, press, audit=audit) as plc, pytest.raises(RuntimeError, match="display broke"):
        plc.run_step(upper, lower, reporter=HookReporter(on_update=display_breaks))
    assert [(e.outcome, e.detail) for e in audit.entries() if e.action == "stop"] == [
        ("ok", "unexpected error: RuntimeError: the progress display broke")]
    flags = sim.wait_idle(5.0)
    assert not flags["busy"] and not flags["in_position"]


def test_nan_or_infinite_motion_timeout_is_refused_before_any_write(start_sim, press, audit):
    sim = start_sim()
    upper, lower = step_setpoints(press)
    with ModbusPress(sim.url, press, audit=audit) as plc:
        for bad in (float("nan"), float("inf"), 0.0):
            with pytest.raises(InputError, match=f"timeout must be a positive number of seconds, got {bad}"):
                plc.run_step(upper, lower, timeout_s=bad)
    assert actions(audit) == [("connect", "ok")]


def test_connect_checks_identity(start_sim, press):
    sim = start_sim(word_order="CDAB")
    with pytest.raises(LinkError, match="uses word order CDAB, but ABCD was requested"):
        ModbusPress(sim.url, press, word_order="ABCD")
    with pytest.raises(ConfigError, match="drives 4 x 6 punches"):
        ModbusPress(sim.url, small_press(5, 6))
    with pytest.raises(LinkError, match="cannot connect"):
        ModbusPress("tcp://127.0.0.1:1?unit=1", press)
    with ModbusPress(sim.url, None, heartbeat_s=None) as plc:  # status only: no press needed
        report = plc.status_report()
        with pytest.raises(InputError, match="press description"):
            plc.run_step(*step_setpoints(press))
    assert report["word_order"] == "CDAB" and report["limits_mm"]["upper"] == [-300.0, 400.0]


def test_a_wrong_unit_id_is_named(start_sim, press):
    sim = start_sim(unit=2)
    with pytest.raises(LinkError, match="not an mppf press PLC with unit id 1: .*exception 4") as info:
        ModbusPress(f"tcp://127.0.0.1:{sim.port}?unit=1&retries=0", press)
    assert "check the unit id" in info.value.hint
    with ModbusPress(f"tcp://127.0.0.1:{sim.port}?unit=2", press, heartbeat_s=None) as plc:
        assert plc.status().ready


@pytest.fixture
def foreign_device():
    """Another Modbus device at a loopback port (a plain pymodbus server full of 0x1234)."""
    from pymodbus.server import ModbusTcpServer
    from pymodbus.simulator import DataType, SimData, SimDevice

    loop = asyncio.new_event_loop()
    thread = threading.Thread(target=loop.run_forever, daemon=True)
    thread.start()

    async def start():
        device = SimDevice(id=1, simdata=[SimData(0, count=200, values=0x1234, datatype=DataType.REGISTERS)])
        server = ModbusTcpServer(device, address=("127.0.0.1", 0))
        await server.serve_forever(background=True)
        return server

    server = asyncio.run_coroutine_threadsafe(start(), loop).result(10)
    yield f"tcp://127.0.0.1:{server.transport.sockets[0].getsockname()[1]}?unit=1"
    asyncio.run_coroutine_threadsafe(server.shutdown(), loop).result(10)
    loop.call_soon_threadsafe(loop.stop)
    thread.join(10)
    loop.close()


def test_a_device_that_is_not_an_mppf_plc_is_refused_untouched(foreign_device, press, audit):
    with pytest.raises(LinkError, match=r"not an mppf press PLC: registers .* hold 0x1234 0x1234"):
        ModbusPress(foreign_device, press, audit=audit)
    assert actions(audit) == [("connect", "failed")]
    with ModbusAdapter(parse_plc_url(foreign_device)) as io:  # no heartbeat, nothing else was written
        assert io.read_holding(0, 200) == [0x1234] * 200


@pytest.mark.usefixtures("steady_gc")
def test_the_heartbeat_after_a_claim_keeps_the_lease(start_sim, press):
    sim = start_sim(watchdog_s=1.0)
    with ModbusPress(sim.url, press, heartbeat_s=0.25) as plc:
        assert plc.heartbeat_period_s == pytest.approx(0.1)  # a tenth of the PLC's watchdog
        time.sleep(0.2)
        assert plc.status_report()["heartbeat"]["counter"] == 0  # no beat before the claim
        plc.claim()
        time.sleep(0.2)
        first = plc.status_report()["heartbeat"]
        time.sleep(0.15)
        second = plc.status_report()
        assert second["status"]["lease_ok"] and second["owner_master"] == plc.master_id
        assert second["heartbeat"]["master"] == plc.master_id and second["heartbeat"]["counter"] != first["counter"]
        assert plc.heartbeat_gap_s() < 1.0 / 4
        plc.stop_heartbeat()
        time.sleep(1.2)
        st = plc.status()
        assert not st.lease_ok and not st.owned


def test_reads_are_retried_commands_are_not(start_sim):
    sim = start_sim()
    sim.inject("slow", delay_ms=400)
    url = parse_plc_url(sim.url)
    with ModbusAdapter(url, timeout_s=0.1, retries=2) as io:
        with pytest.raises(LinkError, match="no reply"):
            io.read_holding(0, 2)
        assert io.requests == 3  # one attempt + two retries
        with pytest.raises(LinkError, match="no reply"):
            io.write_command(load_register_map()["heartbeat_counter"].address, [7])
        assert io.requests == 4  # exactly one attempt


def test_a_refusal_after_go_sends_stop_and_is_a_plc_error_not_a_link_failure(start_sim, press, audit):
    """A PLC that refuses a request while the press moves: STOP is sent at once (the link works),
    and the error is a PlcError (exit code 4), not a lost link (3)."""
    from mppf.core.errors import EXIT_PRESS, PlcError

    sim = start_sim(time_scale=2.0, watchdog_s=None)  # no watchdog: only a STOP ends the motion
    upper, lower = step_setpoints(press)
    with ModbusPress(sim.url, press, audit=audit) as plc:
        read = plc._io.read_holding

        def refuses_during_motion(address, count, **kw):
            if sim.status_bits()["busy"] and address == load_register_map()["stop_request"].address:
                error = PlcError("the PLC at the test refused reading the status: Modbus exception 4")
                error.exception_code = 4
                raise error
            return read(address, count, **kw)

        plc._io.read_holding = refuses_during_motion
        with pytest.raises(PlcError, match="while the press moved after GO; STOP was sent") as info:
            plc.run_step(upper, lower)
    assert not isinstance(info.value, LinkError) and info.value.exit_code == EXIT_PRESS
    assert info.value.exception_code == 4
    assert [(e.outcome, e.detail.split(":")[0]) for e in audit.entries() if e.action == "stop"] == [
        ("ok", "refusal during motion")]
    flags = sim.wait_idle(5.0)
    assert not flags["busy"] and not flags["in_position"]  # stopped short of the targets
