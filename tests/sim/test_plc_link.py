"""The in-process press: the press driver on the simulated PLC's program, instant and seeded."""

from __future__ import annotations

import time

import numpy as np
import pytest
from driver_helpers import HookReporter, actions, open_audit, small_press, step_setpoints

from mppf.core.errors import Cancelled, LimitError, PressFault, PressRefused
from mppf.drivers.follow import motion_time_s
from mppf.sim.faults import parse_fault_spec
from mppf.sim.plc.link import InProcessPress


@pytest.fixture
def press():
    return small_press()


audit = pytest.fixture(open_audit, name="audit")


def test_a_step_is_instant_and_reports_the_programs_positions(press, audit):
    upper, lower = step_setpoints(press)
    reporter = HookReporter()
    started = time.monotonic()
    with InProcessPress(press, audit=audit, job_sha256="a" * 64) as link:
        result = link.run_step(upper, lower, reporter=reporter)
        actual_upper, actual_lower = link.program.actual_positions_mm()
        status = link.status()
    wall_s = time.monotonic() - started
    travel = max(np.abs(upper - press.upper.park_mm).max(), np.abs(lower - press.lower.park_mm).max())
    expected_s = motion_time_s(travel, press.speed_mm_s, press.accel_mm_s2)  # about 20 s of motion
    assert wall_s < 0.2 * expected_s  # simulated time runs as fast as the CPU allows
    assert expected_s * 0.95 < result.duration_s < expected_s + 0.2  # in simulated seconds
    np.testing.assert_allclose(result.actual_upper_mm, actual_upper, atol=0.005)
    np.testing.assert_allclose(result.actual_lower_mm, actual_lower, atol=0.005)
    np.testing.assert_allclose(result.target_upper_mm, upper, atol=1e-9)
    assert result.max_error_mm <= press.position_tolerance_mm and result.sequence == 1
    assert status.in_position and status.lease_ok and status.state == "COMPLETE" and status.motion_sequence == 1
    # the same handshake and audit records as the Modbus driver, with the job hash
    assert [a for a in actions(audit) if a[0] != "connect"] == [
        ("claim", "ok"), ("upload", "ok"), ("upload", "ok"), ("validate", "ok"), ("go", "ok"), ("complete", "ok"),
        ("release", "ok")]
    assert {e.job_sha256 for e in audit.entries() if e.action == "go"} == {"a" * 64}
    assert reporter.tasks[0].startswith("upload") and reporter.tasks[1].startswith("motion") and reporter.updates > 10


def test_positions_are_seeded(press):
    upper, lower = step_setpoints(press)

    def read_back(seed):
        with InProcessPress(press, seed=seed, noise_mm=0.01) as link:
            result = link.run_step(upper, lower)
            return np.concatenate([result.actual_upper_mm, result.actual_lower_mm])

    first, again, other = read_back(4), read_back(4), read_back(5)
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first, other)


def test_strokes_beyond_the_limits_are_a_limit_error_before_any_write(press, audit):
    upper, lower = step_setpoints(press)
    upper[1, 2] = press.upper.max_mm + 10.0
    with InProcessPress(press, audit=audit) as link:
        before = link.program.setpoints_mm()
        with pytest.raises(LimitError, match="upper punch \\(row 2, col 3\\)"):
            link.run_step(upper, lower)
        after = link.program.setpoints_mm()
    for a, b in zip(before, after):
        np.testing.assert_array_equal(a, b)
    assert ("limits", "refused") in actions(audit) and ("upload", "ok") not in actions(audit)


def test_an_estop_is_a_refusal_and_a_fault_during_motion_a_press_fault(press, audit):
    upper, lower = step_setpoints(press)
    with InProcessPress(press, audit=audit, faults=[parse_fault_spec("estop")]) as link:
        with pytest.raises(PressRefused, match="e-stop"):
            link.run_step(upper, lower)
        link.program.release_estop()
        link.reset()
        link.program.inject("overpressure", after_s=2.0)
        with pytest.raises(PressFault, match="OVERPRESSURE.*STOP was sent"):
            link.run_step(upper, lower)
        status = link.status()
    assert status.fault and not status.busy
    assert ("stop", "ok") in actions(audit) and ("complete", "ok") not in actions(audit)


def test_a_stuck_punch_is_named(press):
    upper, lower = step_setpoints(press)
    with InProcessPress(press) as link, pytest.raises(PressFault) as info:
        link.program.inject("stuck", matrix="lower", row=2, col=4, percent=50)
        link.run_step(upper, lower)
    # a punch out of its band is never COMPLETE (map v3): the PLC's positioning timeout names it
    assert "STUCK_PUNCH" in str(info.value) and "lower punch (row 3, col 5)" in str(info.value)


def test_ctrl_c_sends_stop_and_the_press_comes_to_rest_short_of_the_targets(press, audit):
    upper, lower = step_setpoints(press)

    def operator_presses_ctrl_c(completed):
        raise KeyboardInterrupt

    with InProcessPress(press, audit=audit) as link:
        with pytest.raises(Cancelled, match="STOP was sent"):
            link.run_step(upper, lower, reporter=HookReporter(on_update=operator_presses_ctrl_c))
        status = link.status()
        actual_upper = link.program.actual_positions_mm()[0]
    assert [e.detail for e in audit.entries() if e.action == "stop"] == ["cancelled by the operator"]
    assert not status.busy and not status.in_position and np.all(actual_upper > upper + 10.0)


def test_a_halted_program_is_found_from_its_stale_heartbeat_at_once(press, audit):
    upper, lower = step_setpoints(press)
    started = time.monotonic()
    with InProcessPress(press, audit=audit) as link, pytest.raises(PressFault, match="PLC program is not running"):
        link.program.inject("freeze", after_s=1.0)
        link.run_step(upper, lower)
    assert time.monotonic() - started < 5.0
    assert ("stop", "ok") in actions(audit)


def test_the_in_process_press_follows_the_programs_scans_and_ownership(press, audit):
    """The same program as behind Modbus: a second in-process master is refused, STOP from it is obeyed."""
    from mppf.core.errors import PressRefused as Refused

    upper, lower = step_setpoints(press)
    with InProcessPress(press, audit=audit) as link:
        link.run_step(upper, lower)
        with InProcessPress(press, program=link.program) as other:
            with pytest.raises(Refused, match="owned by master"):
                other.run_step(upper + 1, lower)
            assert other._io.writes == 0  # refused before any write
            other.stop("second master")
        assert link.status().state == "STOPPED"
        with pytest.raises(Refused, match="STOPPED by a STOP request of master 0x.*Not confirmed"):
            link.run_step(upper - 1, lower)  # a foreign STOP is never undone without asking
        questions = []
        link.confirm_reset = lambda question: questions.append(question) or True
        result = link.run_step(upper - 1, lower)  # confirmed: the owner resets the stopped job and goes on
    assert f"master 0x{other.master_id:08X}" in questions[0] and "1 STOP request(s)" in questions[0]
    assert ("foreign stop", "not reset") in actions(audit) and ("foreign stop", "reset confirmed") in actions(audit)
    assert result.max_error_mm <= press.position_tolerance_mm
