"""The simulated PLC's program on its own: the state machine of register map v2, scan by scan.

No Modbus, no threads: a raw master stores into the program's register image (as a PLC's
Modbus server does) and the test runs the scans by hand, so every refusal and transition
is checked at the scan it happens.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from driver_helpers import RawMaster

from mppf.core.errors import InputError
from mppf.drivers import codec, regmap as rm
from mppf.drivers.follow import motion_time_s
from mppf.model.press import example_press_path, load_press
from mppf.sim.plc.program import PlcProgram

MAP = rm.load_register_map()
PRESS = dataclasses.replace(load_press(example_press_path()), rows=4, cols=6)
SCAN_S = 0.01


def _targets(seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(40.0, 60.0, PRESS.shape).round(2), rng.uniform(-60.0, -40.0, PRESS.shape).round(2)


def _master(program: PlcProgram, master_id: int) -> RawMaster:
    def write(address, words):
        assert program.store(address, words) is None

    return RawMaster(MAP, write, program.read, lambda: program.advance(SCAN_S), master_id, program.word_order)


@pytest.fixture
def program():
    return PlcProgram(PRESS, watchdog_s=1.0, scan_s=SCAN_S)


@pytest.fixture
def owner(program):
    master = _master(program, 0x11111111)
    assert master.command("CLAIM") == "ACCEPTED"
    return master


def _validated(program, master, sequence=1, seed=0):
    upper, lower = _targets(seed)
    crc = master.upload(upper, lower)
    master.scan()
    assert master.state() == "LOADED"
    assert master.command("VALIDATE", sequence, crc) == "ACCEPTED" and master.state() == "VALIDATED"
    return crc, upper, lower


def _run_until(program, master, states, limit_s=100.0):
    waited = 0.0
    while master.state() not in states:
        master.beat()
        program.advance(0.02)
        waited += 0.02
        assert waited < limit_s, f"still {master.state()}"
    return waited


def test_a_job_moves_in_the_trapezoid_time_and_completes(program, owner):
    crc, upper, lower = _validated(program, owner, 7)
    assert owner.command("GO", 7, crc) == "ACCEPTED" and owner.state() == "EXECUTING" and owner.flags()["busy"]
    elapsed = _run_until(program, owner, ("COMPLETE",))
    travel = max(np.abs(upper - PRESS.upper.park_mm).max(), np.abs(lower - PRESS.lower.park_mm).max())
    assert elapsed == pytest.approx(motion_time_s(travel, PRESS.speed_mm_s, PRESS.accel_mm_s2), abs=0.05)
    np.testing.assert_allclose(program.actual_positions_mm()[0], upper, atol=0.005)
    np.testing.assert_allclose(owner.actuals_mm("lower", PRESS.shape), lower, atol=0.005)
    flags = owner.flags()
    assert flags["in_position"] and flags["ready"] and flags["setpoints_locked"] and not flags["busy"]
    assert (owner.field("motion_sequence"), owner.field("motion_crc")) == (7, crc)
    # a finished job takes no new setpoints and no second GO; RESET brings it back to IDLE
    assert owner.command("GO", 7, crc) == "WRONG_STATE"
    assert owner.command("RESET") == "ACCEPTED" and owner.state() == "IDLE"


def test_the_actual_registers_follow_every_scan_of_a_motion_and_hold_at_rest(program, owner):
    """The scan encodes the actual positions again only when they changed: in motion every scan's registers are
    the positions of that scan, at rest they stay those of the end (and the hydraulics are not stepped)."""
    crc, upper, lower = _validated(program, owner, 3)
    assert owner.command("GO", 3, crc) == "ACCEPTED"
    seen = []
    for _ in range(40):
        owner.beat()
        program.advance(0.02)
        np.testing.assert_allclose(owner.actuals_mm("upper", PRESS.shape), program.actual_positions_mm()[0],
                                   atol=0.005)
        seen.append(owner.actuals_mm("upper", PRESS.shape).copy())
    assert not np.allclose(seen[0], seen[-1])  # they moved
    _run_until(program, owner, ("COMPLETE",))
    position = program.hydraulics.position
    for _ in range(5):
        owner.beat()
        program.advance(0.02)
    assert program.hydraulics.position is position  # at rest: not stepped
    np.testing.assert_allclose(owner.actuals_mm("upper", PRESS.shape), upper, atol=0.005)
    np.testing.assert_allclose(owner.actuals_mm("lower", PRESS.shape), lower, atol=0.005)
    assert MAP.total_registers == max(f.end for f in MAP.fields.values())


def test_a_write_acts_only_on_the_next_scan(program, owner):
    upper, lower = _targets()
    crc = owner.upload(upper, lower)
    assert owner.state() == "IDLE"  # stored, not yet seen
    owner.send("VALIDATE", 1, crc)
    assert owner.field("ack_counter") != owner.counter  # nothing acts inside the request
    owner.scan()  # one scan takes the setpoints and the command
    assert owner.field("ack_counter") == owner.counter and owner.state() == "VALIDATED"


def test_go_without_validation_or_with_a_stale_or_foreign_token_is_refused(program, owner):
    upper, lower = _targets()
    crc = owner.upload(upper, lower)
    owner.scan()
    assert owner.command("GO", 1, crc) == "WRONG_STATE"  # LOADED: not validated
    assert owner.command("VALIDATE", 1, crc) == "ACCEPTED"
    assert owner.command("GO", 1, crc ^ 1) == "TOKEN_MISMATCH"  # a foreign CRC
    assert owner.command("GO", 2, crc) == "TOKEN_MISMATCH"  # another sequence
    assert owner.command("VALIDATE", 2, crc) == "ACCEPTED"
    assert owner.command("GO", 1, crc) == "TOKEN_MISMATCH"  # the stale token of the first validation
    assert owner.command("VALIDATE", 2, crc) == "SEQUENCE_REUSED"  # a sequence is never accepted twice
    assert owner.command("VALIDATE", 0, crc) == "SEQUENCE_REUSED"
    assert owner.command("VALIDATE", 3, crc ^ 1) == "CRC_MISMATCH"
    assert owner.state() == "VALIDATED" and owner.field("validated_sequence") == 2
    assert np.allclose(program.actual_positions_mm()[0], PRESS.upper.park_mm) and not owner.flags()["busy"]


def test_a_setpoint_change_after_validation_drops_back_to_loaded(program, owner):
    crc, _, _ = _validated(program, owner)
    program.write_foreign_setpoint("upper", 1, 2, 55.55)  # another master's write
    owner.scan()
    assert owner.state() == "LOADED" and owner.field("validated_sequence") == 0
    assert owner.command("GO", 1, crc) == "WRONG_STATE"
    assert not owner.flags()["busy"]


def test_a_second_master_cannot_validate_go_reset_or_claim_while_another_owns(program, owner):
    crc, _, _ = _validated(program, owner)
    other = _master(program, 0x22222222)
    assert other.command("CLAIM") == "OWNED_BY_OTHER"
    assert other.command("VALIDATE", 5, crc) == "NOT_OWNER"
    assert other.command("GO", 1, crc) == "NOT_OWNER"
    assert other.command("RESET") == "NOT_OWNER"
    assert other.command("RELEASE") == "NOT_OWNER"
    assert other.command("CLAIM", master=0) == "BAD_MASTER"
    assert owner.state() == "VALIDATED" and owner.field("owner_master") == owner.master_id
    # its upload lands in the registers (the PLC cannot tell who wrote), and costs the owner's validation
    upper, lower = _targets(3)
    other.upload(upper, lower)
    owner.scan()
    assert owner.state() == "LOADED" and owner.command("GO", 1, crc) == "WRONG_STATE"
    assert not owner.flags()["busy"]


def test_setpoint_writes_while_executing_are_undone_and_counted(program, owner):
    crc, upper, _ = _validated(program, owner)
    assert owner.command("GO", 1, crc) == "ACCEPTED"
    before = program.read(MAP["upper_setpoints"].address, 2)
    program.write_foreign_setpoint("upper", 0, 0, 111.11)
    owner.scan()
    assert program.read(MAP["upper_setpoints"].address, 2) == before and owner.field("refused_writes") == 1
    assert owner.state() == "EXECUTING"
    _run_until(program, owner, ("COMPLETE",))
    np.testing.assert_allclose(program.actual_positions_mm()[0], upper, atol=0.005)  # the validated job, untouched
    # a write to a read-only register is undone too
    assert program.store(MAP["state"].address, [7]) is None
    owner.scan()
    assert owner.state() == "COMPLETE" and owner.field("refused_writes") == 2


def test_stop_from_anyone_is_obeyed_and_invalidates_the_job(program, owner):
    crc, upper, _ = _validated(program, owner)
    assert owner.command("GO", 1, crc) == "ACCEPTED"
    for _ in range(20):
        owner.beat()
        program.advance(0.05)
    stranger = _master(program, 0x33333333)  # never claimed
    stranger.stop()
    owner.scan()
    assert owner.state() == "STOPPING" and owner.field("stop_request") == 0 and owner.field("stop_count") == 1
    assert owner.field("last_stop_master") == stranger.master_id
    _run_until(program, owner, ("STOPPED",))
    assert not owner.flags()["in_position"] and np.all(program.actual_positions_mm()[0] > upper + 10.0)
    assert MAP.stop_causes.name(owner.field("stop_cause")) == "STOP_REQUEST"
    # the job is gone: GO after STOP is refused; RESET, then a fresh validation
    assert owner.command("GO", 1, crc) == "WRONG_STATE" and not owner.flags()["busy"]
    assert owner.command("RESET") == "ACCEPTED" and owner.state() == "IDLE"
    # STOP in a state without motion invalidates as well
    crc, _, _ = _validated(program, owner, 2, seed=1)
    owner.stop()
    owner.scan()
    assert owner.state() == "STOPPED" and owner.command("GO", 2, crc) == "WRONG_STATE"


def test_the_lease_lapses_without_heartbeat_and_the_watchdog_stops_motion(program, owner):
    crc, _, _ = _validated(program, owner)
    assert owner.command("GO", 1, crc) == "ACCEPTED"
    for _ in range(10):  # an owner beating every 0.2 s keeps it moving
        owner.beat()
        program.advance(0.2)
    assert owner.state() == "EXECUTING" and owner.flags()["lease_ok"]
    for _ in range(6):  # then 1.2 s of silence
        program.advance(0.2)
    assert owner.state() == "FAULT" and MAP.faults.name(owner.field("fault_code")) == "WATCHDOG"
    assert owner.field("owner_master") == 0 and not owner.flags()["owned"]
    # the lease is gone: another master may claim and reset
    other = _master(program, 0x44444444)
    assert other.command("CLAIM") == "ACCEPTED" and other.command("RESET") == "ACCEPTED"
    assert other.state() == "IDLE"


def test_a_lost_lease_drops_a_validated_job(program, owner):
    _validated(program, owner)
    program.advance(1.5)
    assert owner.state() == "IDLE" and not owner.flags()["owned"]


def test_go_needs_the_key_switch_in_remote_and_local_stops_a_motion(program, owner):
    crc, _, _ = _validated(program, owner)
    program.set_remote(False)
    assert not owner.flags()["remote_enabled"]
    assert owner.command("GO", 1, crc) == "REMOTE_DISABLED" and owner.state() == "VALIDATED"
    program.set_remote(True)
    assert owner.command("GO", 1, crc) == "ACCEPTED"
    program.inject("local", after_s=1.0)
    _run_until(program, owner, ("STOPPED",))
    assert MAP.stop_causes.name(owner.field("stop_cause")) == "REMOTE_DISABLED"


def test_estop_latches_in_any_state_and_reset_waits_for_its_release(program, owner):
    _validated(program, owner)
    program.inject("estop")
    assert owner.state() == "FAULT" and owner.flags()["estop"] and not owner.flags()["ready"]
    assert owner.command("RESET") == "ESTOP_ACTIVE"
    assert owner.command("VALIDATE", 9, 0) == "ESTOP_ACTIVE"  # the e-stop wins over every later check
    program.release_estop()
    assert owner.command("VALIDATE", 9, 0) == "FAULT_ACTIVE"
    assert owner.command("RESET") == "ACCEPTED" and owner.state() == "IDLE" and owner.field("fault_code") == 0


def test_refusal_precedence_follows_the_map(program, owner):
    other = _master(program, 0x55555555)
    program.inject("estop")
    assert other.command("GO", 1, 0) == "NOT_OWNER"  # ownership before the e-stop
    assert owner.command("GO", 1, 0) == "ESTOP_ACTIVE"
    program.store(MAP["command"].address, [99, 4242] + owner.u32(owner.master_id) + [0, 0, 0])
    owner.scan()
    assert owner.result() == "BAD_COMMAND"


def test_a_job_without_travel_completes_in_the_scan_of_its_go(program, owner):
    upper, lower = program.setpoints_mm()  # the power-on setpoints: where the punches are
    crc = owner.upload(upper, lower)
    assert owner.command("VALIDATE", 1, crc) == "ACCEPTED"  # unchanged registers: validated from IDLE
    assert owner.command("GO", 1, crc) == "ACCEPTED"
    assert owner.state() == "COMPLETE" and (owner.field("motion_sequence"), owner.field("motion_crc")) == (1, crc)


def test_a_halted_program_stops_scanning_but_stores_writes(program, owner):
    crc, _, _ = _validated(program, owner)
    program.inject("freeze", after_s=1.0)
    assert owner.command("GO", 1, crc) == "ACCEPTED"
    for _ in range(100):
        owner.beat()
        program.advance(0.05)
    beat, actual = program.heartbeat, program.actual_positions_mm()[0]
    program.advance(1.0)
    assert program.frozen and program.heartbeat == beat and np.array_equal(program.actual_positions_mm()[0], actual)
    assert program.store(MAP["status_word"].address, [0xFFFF]) is None  # no logic: even a status register is written
    assert program.read(MAP["status_word"].address, 1) == [0xFFFF]
    program.clear_faults()
    program.advance(0.05)
    assert program.heartbeat == beat + 1 and program.read(MAP["status_word"].address, 1) != [0xFFFF]


def test_a_write_outside_the_map_is_the_only_exception(program):
    assert program.store(MAP.total_registers - 1, [1, 2]) == MAP.illegal_address
    assert program.store(MAP["magic"].address, [1, 2]) is None  # inside the map: stored, undone at the scan
    program.advance(SCAN_S)
    assert codec.words_to_u32(program.read(0, 2)) == MAP.magic


def test_identity_states_the_scan_time_watchdog_and_tolerance():
    program = PlcProgram(PRESS, watchdog_s=0.75, scan_s=0.05, word_order="CDAB")
    words = program.read(0, 16)
    assert codec.detect_word_order(words[0:2], MAP.magic) == "CDAB"
    assert words[MAP["map_version"].address] == 3
    assert words[MAP["scan_time_max_ms"].address] == 50 and words[MAP["watchdog_ms"].address] == 750
    assert words[MAP["position_tolerance"].address] == round(PRESS.position_tolerance_mm / MAP.count_mm)
    with pytest.raises(InputError, match="at most 200 ms, got 250 ms"):
        PlcProgram(PRESS, scan_s=0.25)


def test_noise_is_seeded():
    def actuals(seed):
        program = PlcProgram(PRESS, seed=seed, noise_mm=0.05)
        program.advance(0.02)
        return program.read(MAP["upper_actuals"].address, 2 * PRESS.rows * PRESS.cols)

    assert actuals(3) == actuals(3) and actuals(3) != actuals(4)


def test_faults_of_the_link_are_not_the_programs():
    program = PlcProgram(PRESS)
    with pytest.raises(InputError, match="fault 'slow' acts on the Modbus link"):
        program.inject("slow", delay_ms=10)
    with pytest.raises(InputError, match="unknown fault 'flood'") as info:
        program.inject("flood")
    assert "stuck, estop, overpressure, freeze, slow, drop, restart" in info.value.hint
    with pytest.raises(InputError, match="fault 'estop': .*unexpected keyword"):
        program.inject("estop", when=3)
