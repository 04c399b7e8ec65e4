"""The simulated PLC's program on its own: no Modbus, no threads, time advanced by hand."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mppf.core.errors import InputError
from mppf.drivers import codec, regmap as rm
from mppf.drivers.follow import motion_time_s
from mppf.planning.press import example_press_path, load_press
from mppf.sim.plc.program import PlcProgram

MAP = rm.load_register_map()
PRESS = dataclasses.replace(load_press(example_press_path()), rows=4, cols=6)


def _targets(seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(40.0, 60.0, PRESS.shape).round(2), rng.uniform(-60.0, -40.0, PRESS.shape).round(2)


def _upload_and_validate(program: PlcProgram, upper, lower, sequence: int):
    words = {side: codec.encode_int32(codec.mm_to_counts(np.ravel(v)), program.word_order)
             for side, v in (("upper", upper), ("lower", lower))}
    for side in ("upper", "lower"):
        assert program.write(MAP[f"{side}_setpoints"].address, words[side]) is None
    crc = codec.setpoint_crc32(words["upper"], words["lower"])
    return program.write(MAP["setpoint_crc"].address, codec.encode_uint32([crc], program.word_order) + [sequence])


def _go(program: PlcProgram, sequence: int):
    return program.write(MAP["command"].address, [MAP.command("GO"), sequence])


def _flags(program: PlcProgram) -> dict:
    return MAP.status_flags(program.read(MAP["status_word"].address, 1)[0])


def _run_until_idle(program: PlcProgram, dt_s: float = 0.02, limit_s: float = 100.0) -> float:
    waited = 0.0
    while _flags(program)["busy"]:
        program.advance(dt_s)
        waited += dt_s
        assert waited < limit_s, "motion did not end"
    return waited


def test_a_step_moves_in_the_trapezoid_time_on_explicit_time_steps():
    program = PlcProgram(PRESS, watchdog_s=None)
    upper, lower = _targets()
    assert _upload_and_validate(program, upper, lower, 7) is None
    assert _go(program, 7) is None and _flags(program)["busy"]
    elapsed = _run_until_idle(program)
    travel = max(np.abs(upper - PRESS.upper.park_mm).max(), np.abs(lower - PRESS.lower.park_mm).max())
    assert elapsed == pytest.approx(motion_time_s(travel, PRESS.speed_mm_s, PRESS.accel_mm_s2), abs=0.05)
    actual_upper, actual_lower = program.actual_positions_mm()
    np.testing.assert_allclose(actual_upper, upper, atol=0.005)
    np.testing.assert_allclose(actual_lower, lower, atol=0.005)
    assert _flags(program)["in_position"] and program.now_s == pytest.approx(elapsed)


def test_refusals_come_back_as_exception_codes_and_nothing_is_applied():
    program = PlcProgram(PRESS)
    upper, lower = _targets()
    before = program.read(MAP["status_word"].address, 1)
    assert program.write(MAP["status_word"].address, [0xFFFF]) == MAP.exceptions["read_only"]
    assert program.read(MAP["status_word"].address, 1) == before
    assert _upload_and_validate(program, upper, lower, 3) is None
    assert _go(program, 4) == MAP.exceptions["refused"]  # not the acknowledged sequence
    assert MAP.fault_codes[program.refusal_code].name == "SEQUENCE_MISMATCH" and not program.busy


def test_the_watchdog_runs_on_the_programs_time():
    program = PlcProgram(PRESS, watchdog_s=0.5)
    upper, lower = _targets()
    assert _upload_and_validate(program, upper, lower, 1) is None
    assert program.write(MAP["master_heartbeat"].address, [1]) is None and _flags(program)["remote"]
    assert _go(program, 1) is None
    for beat in range(2, 12):  # a master beating every 0.2 s keeps it moving
        program.advance(0.2)
        assert program.write(MAP["master_heartbeat"].address, [beat]) is None
    assert program.busy and not program.fault_code
    program.advance(0.3)
    program.advance(0.3)  # then 0.6 s of silence
    assert MAP.fault_codes[program.fault_code].name == "WATCHDOG" and not _flags(program)["remote"]


def test_a_halted_program_stops_scanning_but_stores_writes():
    program = PlcProgram(PRESS)
    upper, lower = _targets()
    program.inject("freeze", after_s=1.0)
    assert _upload_and_validate(program, upper, lower, 1) is None and _go(program, 1) is None
    for _ in range(100):
        program.advance(0.05)
    beat, actual = program.heartbeat, program.actual_positions_mm()[0]
    program.advance(1.0)
    assert program.frozen and program.heartbeat == beat and np.array_equal(program.actual_positions_mm()[0], actual)
    assert program.write(MAP["status_word"].address, [0xFFFF]) is None  # no logic: even a status register is written
    program.clear_faults()
    program.advance(0.05)
    assert program.heartbeat == beat + 1


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
