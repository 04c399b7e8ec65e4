"""The driver against PLCs and masters that broke earlier drivers: the simulated PLC's quirks, over real TCP.

Each scenario of docs/register-map.md section 15 that a misread PLC or a foreign master
produces: the press must be at rest when the driver is done, the message true, the lease
given back only then.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from driver_helpers import HookReporter, actions, open_audit, small_press, step_setpoints

from mppf.core.errors import PressFault, PressRefused
from mppf.drivers.modbus import ModbusPress
from mppf.drivers.regmap import load_register_map
from mppf.sim.plc.host import start_simulated_plc
from mppf.sim.plc.link import InProcessPress
from mppf.sim.plc.quirks import FOREIGN_MASTER

FAST = 20.0
MAP = load_register_map()


@pytest.fixture
def press():
    return small_press()


@pytest.fixture
def start_sim(press):
    handles = []

    def start(*quirks, **options):
        options.setdefault("time_scale", FAST)
        options.setdefault("watchdog_s", 2.0)
        handle = start_simulated_plc(press, quirks=list(quirks), **options)
        handles.append(handle)
        return handle

    yield start
    for handle in handles:
        handle.stop()


audit = pytest.fixture(open_audit, name="audit")


def at_rest(sim) -> bool:
    return not sim._call(lambda: sim.plc.hydraulics.moving) and not sim.status_bits()["busy"]


def test_a_literal_complete_is_caught_stopped_and_released_only_at_rest(start_sim, press, audit):
    sim = start_sim("literal-complete", time_scale=2.0)  # a slow move: the punches still run after COMPLETE
    upper, lower = step_setpoints(press)
    with ModbusPress(sim.url, press, audit=audit) as plc, pytest.raises(PressFault) as info:
        plc.run_step(upper, lower)
    message = str(info.value)
    assert "the PLC reported COMPLETE with" in message and "not in position" in message
    assert "STOP was sent and the press came to rest" in message
    assert at_rest(sim) and sim.state() == "STOPPED"
    steps = actions(audit)
    assert steps.index(("stop", "ok")) < steps.index(("release", "ok"))  # the lease kept until at rest
    assert sim._call(lambda: sim.plc.owner) == 0


def test_a_literal_complete_sooner_than_the_move_is_refused_by_its_duration(start_sim, press, audit):
    sim = start_sim("literal-complete", time_scale=2.0)
    upper, lower = step_setpoints(press)
    with ModbusPress(sim.url, press, audit=audit, motion_time_scale=2.0) as plc, pytest.raises(PressFault) as info:
        plc.run_step(upper, lower)
    assert "the PLC reported COMPLETE after" in str(info.value) and "STOP was sent" in str(info.value)
    assert ("complete", "too soon") in actions(audit) and at_rest(sim)


@pytest.mark.parametrize("late", [1, 3])
def test_status_bits_scans_late_still_complete(start_sim, press, late):
    sim = start_sim(f"late-status:{late}")
    upper, lower = step_setpoints(press)
    with ModbusPress(sim.url, press) as plc:
        first = plc.run_step(upper, lower)
        second = plc.run_step(upper - 3.0, lower + 3.0)
    assert max(first.max_error_mm, second.max_error_mm) <= press.position_tolerance_mm


def test_a_master_borrowing_the_owners_id_is_refused_and_the_job_completes(start_sim, press, audit):
    sim = start_sim("borrow-ids")
    upper, lower = step_setpoints(press)
    # the driver pauses after VALIDATE long enough for the thief's GO to be taken first
    reporter = HookReporter(on_info=lambda m: time.sleep(0.2) if "validated by the PLC" in m else None)
    with ModbusPress(sim.url, press, audit=audit) as plc:
        result = plc.run_step(upper, lower, reporter=reporter)
    assert result.max_error_mm <= press.position_tolerance_mm
    assert ("GO", "BAD_AUTH") in sim._call(lambda: list(sim.plc.foreign_results))  # the thief's GO, refused
    assert ("go", "ok") in actions(audit) and ("complete", "ok") in actions(audit)


def test_beats_in_a_dead_owners_name_do_not_keep_its_lease(start_sim, press):
    sim = start_sim("borrow-ids", time_scale=2.0, watchdog_s=1.0)
    upper, lower = step_setpoints(press)
    plc = ModbusPress(sim.url, press)
    reporter = HookReporter(on_start=lambda task: plc.stop_heartbeat() if task.startswith("motion") else None)
    try:
        with pytest.raises(PressFault, match="WATCHDOG"):
            plc.run_step(upper, lower, reporter=reporter)  # the owner's heartbeat dies as the motion starts
    finally:
        plc._io.close()
    assert MAP.faults.name(sim.fault_code()) == "WATCHDOG"
    deadline = time.monotonic() + 10
    while not at_rest(sim):
        assert time.monotonic() < deadline
        time.sleep(0.05)


def test_a_foreign_none_after_go_does_not_hide_the_go(start_sim, press, audit):
    sim = start_sim("none-after-go", scan_s=0.05)
    upper, lower = step_setpoints(press)
    with ModbusPress(sim.url, press, audit=audit) as plc:
        result = plc.run_step(upper, lower)
    assert result.max_error_mm <= press.position_tolerance_mm
    assert ("go", "ok") in actions(audit) and ("stop", "ok") not in actions(audit)
    assert sim._call(lambda: list(sim.plc.foreign_results)) == [("NONE", "ACCEPTED")]


def test_a_foreign_stop_is_named_and_not_undone_without_asking(start_sim, press, audit):
    sim = start_sim("foreign-stop@0.5", time_scale=5.0)
    upper, lower = step_setpoints(press)
    with ModbusPress(sim.url, press, audit=audit) as plc:
        with pytest.raises(PressFault, match=f"stopped by a STOP request of master 0x{FOREIGN_MASTER:08X}"):
            plc.run_step(upper, lower)
        assert at_rest(sim) and sim.state() == "STOPPED"
        with pytest.raises(PressRefused, match=f"STOPPED by a STOP request of master 0x{FOREIGN_MASTER:08X}"):
            plc.run_step(upper, lower)
        assert sim.state() == "STOPPED"  # nothing written, nothing reset
        plc.confirm_reset = lambda question: True
        result = plc.run_step(upper, lower)
    assert result.max_error_mm <= press.position_tolerance_mm


def test_foreign_setpoint_writes_undone_during_the_job_are_reported(start_sim, press, audit):
    sim = start_sim(time_scale=5.0)
    upper, lower = step_setpoints(press)

    def write(task):
        if task.startswith("motion"):
            sim._call(sim.plc.write_foreign_setpoint, "upper", 1, 1, 77.0)

    reporter = HookReporter(on_start=write)
    with ModbusPress(sim.url, press, audit=audit) as plc:
        plc.run_step(upper, lower, reporter=reporter)
    warning = [m for m in reporter.messages if m.startswith("WARNING")]
    assert warning and "undid setpoint writes in 1 scan(s)" in warning[0]
    assert ("foreign writes", "undone") in actions(audit)
    np.testing.assert_allclose(sim.setpoints_mm()[0], upper, atol=1e-9)  # the job's setpoints were kept


def test_a_refused_go_while_the_press_moves_is_never_nothing_moved(press, audit):
    upper, lower = step_setpoints(press)
    link = InProcessPress(press, audit=audit)

    def moving_already(message):  # a PLC that starts the job on its own before our GO (a broken PLC program)
        if "validated by the PLC" in message:
            link.program._do_go(link.master_id)

    with link, pytest.raises(PressFault) as info:
        link.run_step(upper, lower, reporter=HookReporter(on_info=moving_already))
    assert "the press was moving" in str(info.value) and "STOP was sent" in str(info.value)
    assert "nothing moved" not in str(info.value)
    assert not link.program.hydraulics.moving and ("stop", "ok") in actions(audit)


def test_a_plc_of_another_map_version_is_refused_with_exit_3(start_sim, press):
    from mppf.cli import main

    sim = start_sim()
    sim._call(lambda: sim.plc.regs.__setitem__(MAP["map_version"].address, 2))
    sim._call(lambda: sim.plc._shadow.__setitem__(MAP["map_version"].address, 2))
    assert main(["status", "--plc", sim.url]) == 3


@pytest.mark.parametrize("what, result", [("neighbour", "NEIGHBOUR_STEP"), ("gap", "TIP_GAP")])
def test_the_plc_refuses_a_job_beyond_its_own_limits_whatever_the_master_believes(start_sim, press, audit, what,
                                                                                   result):
    """The master's press description claims a dimpling limit of 300 mm; the PLC keeps its own 30 mm."""
    import dataclasses

    believed = dataclasses.replace(press, max_neighbour_diff_mm=300.0)
    upper, lower = step_setpoints(press)
    if what == "neighbour":
        upper[1, 2] += 100.0  # one pair raised 100 mm
        lower[1, 2] += 100.0
    else:
        upper = lower + 1.0  # every pair's tips 1 mm apart (the neighbours alike: only the gap is wrong)
    sim = start_sim()
    with ModbusPress(sim.url, believed, audit=audit) as plc, pytest.raises(PressRefused) as info:
        plc.run_step(upper, lower)
    assert result in str(info.value) and "GO was not sent" in str(info.value)
    assert "dimpling limit 30 mm" in info.value.hint
    assert ("validate", "refused") in actions(audit) and ("go", "ok") not in actions(audit)
    assert at_rest(sim) and sim.state() == "IDLE"  # released: the refused job dropped


def test_a_foreign_stop_right_after_go_is_named_whenever_the_driver_first_sees_it(start_sim, press, audit):
    """The STOP may land before the driver's first status read after GO: STOPPING with our token is our job, stopped."""
    sim = start_sim("foreign-stop@0", scan_s=0.005)
    upper, lower = step_setpoints(press)
    with ModbusPress(sim.url, press, audit=audit) as plc, \
            pytest.raises(PressFault, match=f"stopped by a STOP request of master 0x{FOREIGN_MASTER:08X}"):
        plc.run_step(upper, lower)
    assert at_rest(sim)
