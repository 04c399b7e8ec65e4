"""The simulated press PLC, driven by a raw pymodbus master over real sockets and a pty."""

from __future__ import annotations

import dataclasses
import os
import re
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from driver_helpers import RawMaster
from mppf.drivers import codec
from mppf.drivers import regmap as rm
from mppf.drivers.url import parse_plc_url
from mppf.sim.plc.host import run_simulated_plc
from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.exceptions import ConnectionException, ModbusIOException
from test_faults import BAD_SPECS

from mppf.cli import main
from mppf.core.errors import InputError
from mppf.model.press import example_press_path, load_press

MAP = rm.load_register_map()
PRESS = dataclasses.replace(load_press(example_press_path()), rows=4, cols=6)
SCALE = 100.0  # motion 100x faster than real time


class Master(RawMaster):
    """A bare Modbus master over a socket speaking the register map (the test's own, not the driver)."""

    def __init__(self, sim, word_order="ABCD", master_id=0x0BADCAFE):
        self.sim = sim
        self.client = ModbusTcpClient("127.0.0.1", port=sim.port, timeout=1.0, retries=0)
        assert self.client.connect()
        super().__init__(MAP, self.write_ok, self.read_at, lambda: sim.scans(2), master_id, word_order)

    def read_at(self, address, count):
        rr = self.client.read_holding_registers(address, count=count, device_id=1)
        assert not rr.isError(), rr
        return rr.registers

    def read(self, name, count=None):
        field = MAP[name]
        return self.read_at(field.address, count or field.count)

    def write(self, address, words):
        """Write; return the exception code (None if accepted)."""
        rr = self.client.write_registers(address, list(words), device_id=1)
        return rr.exception_code if rr.isError() else None

    def write_ok(self, address, words):
        assert self.write(address, words) is None

    def validated(self, upper, lower, sequence):
        crc = self.upload(upper, lower)
        assert self.command("VALIDATE", sequence, crc) == "ACCEPTED"
        return crc

    def wait_state(self, *states, timeout_s=5.0):
        deadline = time.monotonic() + timeout_s
        while self.state() not in states:
            assert time.monotonic() < deadline, f"still {self.state()}"
            self.beat()
            time.sleep(0.01)
        return self.flags()

    def close(self):
        self.client.close()


def targets(seed=0):
    rng = np.random.default_rng(seed)
    upper = rng.uniform(40.0, 60.0, PRESS.shape).round(2)
    lower = rng.uniform(-60.0, -40.0, PRESS.shape).round(2)
    return upper, lower


@pytest.fixture
def plc(request):
    """(sim, claimed master); ``@pytest.mark.parametrize("plc", [scale], indirect=True)`` sets the time scale."""
    with run_simulated_plc(PRESS, time_scale=getattr(request, "param", SCALE), watchdog_s=None) as sim:
        master = Master(sim)
        assert master.command("CLAIM") == "ACCEPTED"
        yield sim, master
        master.close()


# ------------------------------------------------------------------ identity ------
@pytest.mark.parametrize("word_order", ["ABCD", "CDAB"])
def test_magic_and_identity_in_both_word_orders(word_order):
    with run_simulated_plc(PRESS, word_order=word_order, scan_s=0.02, watchdog_s=0.8) as sim:
        master = Master(sim, word_order)
        words = master.read("magic")
        assert codec.detect_word_order(words, MAP.magic) == word_order
        assert master.read("map_version") == [MAP.version] == [3]
        assert master.read("rows") + master.read("cols") == [PRESS.rows, PRESS.cols]
        assert master.read("scan_time_max_ms") + master.read("watchdog_ms") == [20, 800]
        limit = codec.decode_int32(master.read("upper_max"), word_order)[0]
        assert limit * MAP.count_mm == pytest.approx(PRESS.upper.max_mm)
        # power-on: IDLE, no owner, punches parked, setpoints equal to the actual positions
        assert master.state() == "IDLE" and master.field("owner_master") == 0
        assert np.allclose(master.actuals_mm("lower", PRESS.shape), PRESS.lower.park_mm)
        assert sim.url == f"tcp://127.0.0.1:{sim.port}?unit=1"
        url = parse_plc_url(sim.url)  # the driver's URL grammar
        assert (url.scheme, url.host, url.port, url.unit) == ("tcp", "127.0.0.1", sim.port, 1)
        master.close()


def test_writes_to_read_only_registers_are_undone_at_the_next_scan(plc):
    sim, master = plc
    for name in ("magic", "status_word", "owner_master", "upper_actuals"):
        before = master.read(name, 2 if MAP[name].count > 1 else 1)
        assert master.write(MAP[name].address, [1] * len(before)) is None  # stored: no exception inside the map
        master.scan()
        assert master.read(name, len(before)) == before
    assert master.field("refused_writes") == 4
    # a write beyond the map is the only exception: ILLEGAL DATA ADDRESS, nothing stored
    assert master.write(MAP.total_registers - 1, [1, 2]) == MAP.illegal_address


# -------------------------------------------------------------------- motion ------
MOTION_SCALE = 25.0
"""The timed motion's scale: about 1 s long, so that it is still moving when read back on a busy machine."""


@pytest.mark.parametrize("plc", [MOTION_SCALE], indirect=True)
def test_motion_completes_at_the_setpoints(plc):
    sim, master = plc
    upper, lower = targets()
    crc = master.upload(upper, lower)
    master.scan()
    assert master.state() == "LOADED"
    assert master.command("VALIDATE", 7, crc) == "ACCEPTED"
    assert master.state() == "VALIDATED" and master.field("validated_sequence") == 7
    started = time.monotonic()
    assert master.command("GO", 7, crc) == "ACCEPTED"
    assert master.flags()["busy"] and master.state() == "EXECUTING"
    assert master.command("GO", 7, crc) == "WRONG_STATE"  # a repeated GO cannot start a second motion
    flags = master.wait_state("COMPLETE")
    elapsed = time.monotonic() - started
    assert flags["in_position"] and flags["ready"] and not flags["fault"]
    assert np.allclose(master.actuals_mm("upper", PRESS.shape), upper, atol=0.005)
    assert np.allclose(master.actuals_mm("lower", PRESS.shape), lower, atol=0.005)
    assert master.field("motion_sequence") == 7 and master.field("motion_crc") == crc
    # trapezoid: longest travel 400 + 60 mm (lower park -400 -> -40 ... -60) at 20 mm/s
    travel = max(np.abs(upper - PRESS.upper.park_mm).max(), np.abs(lower - PRESS.lower.park_mm).max())
    expected_s = (travel / PRESS.speed_mm_s + PRESS.speed_mm_s / PRESS.accel_mm_s2) / MOTION_SCALE
    assert 0.8 * expected_s < elapsed < expected_s + 0.5
    hb = master.read("plc_heartbeat")[0]
    time.sleep(0.1)
    assert master.read("plc_heartbeat")[0] != hb


def test_stop_decelerates_short_of_the_target(plc):
    sim, master = plc
    upper, lower = targets()
    crc = master.validated(upper, lower, 3)
    assert master.command("GO", 3, crc) == "ACCEPTED"
    time.sleep(0.05)
    master.stop()
    flags = master.wait_state("STOPPED")
    assert not flags["in_position"] and master.field("stop_count") == 1
    actual_upper, _ = sim.actual_positions_mm()
    assert np.all(actual_upper > upper + 10.0)  # stopped on the way down from 400 mm
    time.sleep(0.05)
    assert np.array_equal(sim.actual_positions_mm()[0], actual_upper)  # at rest


# -------------------------------------------------------------------- checks ------
def test_go_refused_after_a_foreign_setpoint_write(plc):
    sim, master = plc
    upper, lower = targets()
    crc = master.validated(upper, lower, 5)
    sim.write_foreign_setpoint("upper", 1, 2, 55.55)
    assert master.command("GO", 5, crc) == "WRONG_STATE" and master.state() == "LOADED"
    assert not master.flags()["busy"]
    assert np.allclose(sim.actual_positions_mm()[0], PRESS.upper.park_mm)


def test_validation_refused_on_wrong_crc_and_beyond_limits(plc):
    sim, master = plc
    upper, lower = targets()
    crc = master.upload(upper, lower)
    assert master.command("VALIDATE", 4, crc ^ 1) == "CRC_MISMATCH"
    assert master.field("validated_sequence") == 0 and master.state() == "LOADED"
    upper[0, 0] = PRESS.upper.max_mm + 0.01
    crc = master.upload(upper, lower)
    assert master.command("VALIDATE", 4, crc) == "LIMIT"
    assert master.command("GO", 4, crc) == "WRONG_STATE"  # nothing validated
    assert not master.flags()["busy"]


def test_go_refused_on_a_token_mismatch(plc):
    sim, master = plc
    upper, lower = targets()
    crc = master.validated(upper, lower, 9)
    assert master.command("GO", 8, crc) == "TOKEN_MISMATCH"
    assert master.command("GO", 9, crc) == "ACCEPTED"
    master.wait_state("COMPLETE")
    assert master.result() == "ACCEPTED"


def test_estop_refuses_go_and_reset_until_released(plc):
    sim, master = plc
    upper, lower = targets()
    crc = master.validated(upper, lower, 2)
    sim.inject("estop")
    flags = master.flags()
    assert flags["estop"] and flags["fault"] and not flags["ready"] and master.state() == "FAULT"
    assert MAP.faults.name(master.field("fault_code")) == "ESTOP"
    assert master.command("GO", 2, crc) == "ESTOP_ACTIVE"
    assert master.command("RESET") == "ESTOP_ACTIVE"
    sim.release_estop()
    assert master.command("GO", 2, crc) == "FAULT_ACTIVE"
    assert master.command("RESET") == "ACCEPTED"
    assert master.flags()["ready"] and master.field("fault_code") == 0 and master.state() == "IDLE"
    assert master.command("GO", 2, crc) == "WRONG_STATE"  # RESET dropped the job: validate again
    crc = master.validated(upper, lower, 3)
    assert master.command("GO", 3, crc) == "ACCEPTED"
    assert master.wait_state("COMPLETE")["in_position"]


@pytest.mark.parametrize("kind", ["estop", "overpressure"])
def test_fault_during_motion_halts_the_punches(plc, kind):
    sim, master = plc
    upper, lower = targets()
    sim.inject(kind, after_s=3.0)  # 3 s of simulated motion
    crc = master.validated(upper, lower, 1)
    assert master.command("GO", 1, crc) == "ACCEPTED"
    flags = master.wait_state("FAULT")
    sim.wait_idle()
    assert flags["fault"] and not master.flags()["in_position"] and flags["estop"] == (kind == "estop")
    assert MAP.faults.name(master.field("fault_code")) == kind.upper()
    actual_upper = master.actuals_mm("upper", PRESS.shape)
    # about 3 s of motion from 400 mm at 20 mm/s with 100 mm/s2: 400 - (0.5*100*0.2**2 + 20*2.8) = 342 mm
    assert np.all((actual_upper > 330.0) & (actual_upper < 352.0))


def test_freeze_halts_the_program_but_the_link_still_answers(plc):
    sim, master = plc
    upper, lower = targets()
    sim.inject("freeze", after_s=3.0)
    crc = master.validated(upper, lower, 1)
    assert master.command("GO", 1, crc) == "ACCEPTED"
    deadline = time.monotonic() + 5.0
    while not sim.plc.frozen:
        assert time.monotonic() < deadline, "the freeze did not happen"
        time.sleep(0.01)
    beat, actual = master.read("plc_heartbeat"), master.actuals_mm("upper", PRESS.shape)
    time.sleep(0.2)  # twenty scan periods
    assert master.read("plc_heartbeat") == beat and (master.actuals_mm("upper", PRESS.shape) == actual).all()
    assert master.flags()["busy"]  # frozen status: still says moving
    assert np.all((actual > 330.0) & (actual < 352.0))  # halted about 3 s into the move (see above)
    master.stop()  # stored in memory; nothing acts on it
    time.sleep(0.05)
    assert master.field("stop_request") == 1
    sim.clear_faults()  # the program runs again, and takes the STOP
    time.sleep(0.1)
    assert not master.flags()["busy"] and master.read("plc_heartbeat") != beat and master.state() == "STOPPED"


def test_watchdog_stops_motion_when_the_heartbeat_goes_stale():
    with run_simulated_plc(PRESS, time_scale=2.0, watchdog_s=0.3) as sim:
        master = Master(sim)
        assert master.command("CLAIM") == "ACCEPTED"
        master.beat()
        upper, lower = targets()
        crc = master.validated(upper, lower, 1)
        master.beat()
        assert master.flags()["lease_ok"]
        assert master.command("GO", 1, crc) == "ACCEPTED"
        for _ in range(4):  # heartbeats keep it moving
            time.sleep(0.1)
            master.beat()
        assert master.flags()["busy"] and master.state() == "EXECUTING"
        time.sleep(0.5)  # then the master falls silent
        sim.wait_idle()
        flags = master.flags()
        assert flags["fault"] and not flags["lease_ok"] and not flags["owned"] and master.state() == "FAULT"
        assert MAP.faults.name(master.field("fault_code")) == "WATCHDOG"
        assert np.all(master.actuals_mm("upper", PRESS.shape) > 300.0)
        master.close()


# -------------------------------------------------------------------- faults ------
def test_stuck_punch_is_never_complete_and_latches_after_the_positioning_timeout(plc):
    sim, master = plc
    upper, lower = targets()
    sim.inject("stuck", matrix="lower", row=2, col=3, percent=25)
    crc = master.validated(upper, lower, 1)
    assert master.command("GO", 1, crc) == "ACCEPTED"
    flags = master.wait_state("FAULT")  # out of its band: never COMPLETE (map v3, "at rest")
    assert flags["fault"] and not flags["in_position"] and master.read("fault_code") == [MAP.fault("STUCK_PUNCH")]
    error = np.abs(master.actuals_mm("lower", PRESS.shape) - lower)
    assert error[2, 3] == pytest.approx(0.75 * abs(lower[2, 3] - PRESS.lower.park_mm), abs=0.01)
    error[2, 3] = 0
    assert error.max() < 0.006
    bits = codec.unpack_bits(master.read("lower_fault_bits", 2), PRESS.rows * PRESS.cols)
    assert bits.sum() == 1 and bits[2 * PRESS.cols + 3]


def test_stuck_punch_with_fault_timer_sets_its_fault_bit(plc):
    sim, master = plc
    upper, lower = targets()
    sim.inject("stuck", matrix="upper", row=1, col=4, percent=50, fault_after_s=2.0)
    crc = master.validated(upper, lower, 1)
    assert master.command("GO", 1, crc) == "ACCEPTED"
    flags = master.wait_state("FAULT")
    assert flags["fault"] and MAP.faults.name(master.field("fault_code")) == "STUCK_PUNCH"
    bits = codec.unpack_bits(master.read("upper_fault_bits", 2), PRESS.rows * PRESS.cols)
    assert np.flatnonzero(bits).tolist() == [MAP.punch_index(1, 4, PRESS.cols)]
    assert master.command("RESET") == "ACCEPTED"
    assert not any(master.read("upper_fault_bits", 2)) and not master.flags()["fault"]


def test_slow_replies(plc):
    sim, master = plc
    sim.inject("slow", delay_ms=150)
    started = time.monotonic()
    master.read("magic")
    assert time.monotonic() - started >= 0.15
    sim.clear_faults()
    started = time.monotonic()
    master.read("magic")
    assert time.monotonic() - started < 0.1


def test_link_faults_timed_from_the_start_of_motion(plc):
    sim, master = plc
    sim.inject("slow", delay_ms=120, after_s=2.0)  # 2 simulated s into the next motion (0.02 s wall)
    started = time.monotonic()
    master.read("magic")
    assert time.monotonic() - started < 0.1  # not before the motion
    upper, lower = targets()
    crc = master.validated(upper, lower, 1)
    assert master.command("GO", 1, crc) == "ACCEPTED"
    time.sleep(0.1)
    started = time.monotonic()
    master.read("magic")
    assert time.monotonic() - started >= 0.12


def test_dropped_connection_and_recovery(plc):
    sim, master = plc
    sim.drop_connections(0.6)
    with pytest.raises((ConnectionException, ModbusIOException)):
        master.read("magic")
    time.sleep(0.8)
    master.client.close()
    assert master.client.connect()
    assert codec.detect_word_order(master.read("magic"), MAP.magic) == "ABCD"


def test_drop_on_a_write_leaves_it_unapplied(plc):
    sim, master = plc
    sim.inject("drop", after_writes=2, duration_s=0.3)
    assert master.write(MAP["upper_setpoints"].address, codec.encode_int32([100], "ABCD")) is None
    with pytest.raises((ConnectionException, ModbusIOException)):
        master.write(MAP["upper_setpoints"].address + 2, codec.encode_int32([200], "ABCD"))
    time.sleep(0.6)
    master.client.close()
    assert master.client.connect()
    words = master.read("upper_setpoints", 4)
    assert codec.decode_int32(words, "ABCD").tolist() == [100, round(PRESS.upper.park_mm * 100)]


def test_restart_loses_the_owner_and_the_job(plc):
    sim, master = plc
    upper, lower = targets()
    crc = master.validated(upper, lower, 11)
    assert master.command("GO", 11, crc) == "ACCEPTED"
    master.wait_state("COMPLETE")
    sim.restart(downtime_s=0.2)
    time.sleep(0.4)
    master.client.close()
    assert master.client.connect()
    assert master.state() == "IDLE" and master.field("owner_master") == 0 and master.field("last_sequence") == 0
    assert master.command("GO", 11, crc) == "NOT_OWNER"
    assert master.command("CLAIM") == "ACCEPTED" and master.command("GO", 11, crc) == "WRONG_STATE"
    assert np.allclose(master.actuals_mm("upper", PRESS.shape), upper, atol=0.005)  # the punches stayed put


def test_inject_rejects_bad_parameters(plc):
    sim, _ = plc
    with pytest.raises(InputError, match="row 4, col 0 outside"):
        sim.inject("stuck", matrix="upper", row=4, col=0)
    with pytest.raises(InputError, match="unknown fault 'flood'"):
        sim.inject("flood")
    with pytest.raises(InputError, match="unexpected keyword"):
        sim.inject("slow", delay=3)


# ----------------------------------------------------------------------- RTU ------
@pytest.mark.rtu
@pytest.mark.parametrize("word_order", ["ABCD", "CDAB"])
def test_rtu_over_a_pty_pair(word_order):
    with run_simulated_plc(PRESS, rtu=True, baud=115200, word_order=word_order) as sim:
        match = re.fullmatch(r"rtu://(/dev/pts/\d+)\?baud=115200&parity=([NEO])&unit=1", sim.url)
        assert match, sim.url
        url = parse_plc_url(sim.url)  # the driver's URL grammar
        assert (url.device, url.baud, url.parity) == (sim.serial_port, 115200, match.group(2))
        client = ModbusSerialClient(match.group(1), baudrate=115200, parity=match.group(2), timeout=1.0, retries=0)
        assert client.connect()
        try:
            rr = client.read_holding_registers(MAP["magic"].address, count=2, device_id=1)
            assert not rr.isError(), rr
            assert codec.detect_word_order(rr.registers, MAP.magic) == word_order
            rr = client.write_registers(MAP.total_registers - 1, [1, 2], device_id=1)
            assert rr.isError() and rr.exception_code == MAP.illegal_address
        finally:
            client.close()


@pytest.mark.slow  # needs socat
@pytest.mark.rtu
def test_rtu_on_a_serial_device_made_by_socat(tmp_path):
    """The rtu_port= path (a real serial device), on a socat pty pair."""
    socat = shutil.which("socat")
    if socat is None:
        if os.environ.get("CI") == "true":
            pytest.fail("socat is not installed on CI")
        pytest.skip("socat is not installed")
    port_a, port_b = tmp_path / "ttyA", tmp_path / "ttyB"
    proc = subprocess.Popen(
        [socat, f"pty,raw,echo=0,link={port_a}", f"pty,raw,echo=0,link={port_b}"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 5.0
        while not (port_a.exists() and port_b.exists()):
            assert time.monotonic() < deadline, "socat made no pty pair"
            time.sleep(0.02)
        with run_simulated_plc(PRESS, rtu_port=str(port_a), baud=38400, parity="N") as sim:
            assert sim.url == f"rtu://{port_a}?baud=38400&parity=N&unit=1"
            client = ModbusSerialClient(str(port_b), baudrate=38400, parity="N", timeout=1.0, retries=0)
            assert client.connect()
            try:
                rr = client.read_holding_registers(MAP["rows"].address, count=2, device_id=1)
                assert not rr.isError(), rr
                assert rr.registers == [PRESS.rows, PRESS.cols]
            finally:
                client.close()
    finally:
        proc.terminate()
        proc.wait(timeout=5)


# ----------------------------------------------------------------------- CLI ------


@pytest.mark.parametrize("spec, message", BAD_SPECS)
def test_bad_fault_spec_exits_2_with_one_message(capsys, spec, message):
    assert main(["sim", "--port", "0", "--fault", spec]) == 2
    err = capsys.readouterr().err
    assert message in " ".join(err.split())
    assert "Traceback" not in err


def test_sim_command_serves_until_interrupted():
    proc = subprocess.Popen(
        [sys.executable, "-m", "mppf", "sim", "--port", "0", "--word-order", "CDAB", "--status-every", "0.2"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        line = proc.stdout.readline()
        match = re.search(r"tcp://127\.0\.0\.1:(\d+)\?unit=1", line)
        assert match, line
        client = ModbusTcpClient("127.0.0.1", port=int(match.group(1)), timeout=1.0, retries=0)
        assert client.connect()
        rr = client.read_holding_registers(MAP["magic"].address, count=2, device_id=1)
        client.close()
        assert codec.detect_word_order(rr.registers, MAP.magic) == "CDAB"
        time.sleep(0.3)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=10)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    assert "ready" in out and "simulated PLC stopped" in out
