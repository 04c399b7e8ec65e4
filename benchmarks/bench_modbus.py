"""Benchmark: one upload of 2 x 32 x 32 int32 setpoints through the driver, against its wire time.

An upload (:meth:`ModbusPress.upload`, register map v2) is what the driver does before GO:
the readiness read, CLAIM through the command mailbox and its acknowledgement, the sequence
read, 34 FC16 frames of <= 122 registers, 34 FC3 read-back frames of <= 124 registers,
VALIDATE with the job token and its acknowledgement. The frames the driver really sends
are recorded (every request of the adapter), so that the references replay exactly them:

1. Modbus TCP on loopback: the driver against a bare pymodbus loop sending the same frames
   with no checks and no waiting. Target: driver overhead at most 25 %.
2. Modbus RTU at 115200 baud through a pseudo-terminal relay that paces bytes at the baud
   rate (:class:`mppf.sim.serial_pty.PtyPair`): the driver against the theoretical wire
   time of its frames, 11 bits per byte plus the 3.5-character silence before every frame
   (request and reply). Target: at most 1.10 x. In turn on the same link: the bare pymodbus
   loop, and the floor of the link itself (the same frames prebuilt, written with pyserial,
   replies read with exact lengths: what the relay, the simulated PLC and the machine's
   scheduling cost with no master at all). The driver's waits for the PLC's scans (the
   acknowledgements of CLAIM and VALIDATE, scan time 10 ms) are part of its time.

Run: ``python benchmarks/bench_modbus.py [--repeat N] [--rtu-repeat M]``. The bare loops
import pymodbus and pyserial directly on purpose: they are the references the adapter is
measured against.
"""

from __future__ import annotations

import argparse
import logging
import statistics
import time

import numpy as np
import serial
from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.framer import FramerRTU
from pymodbus.pdu import DecodePDU
from pymodbus.pdu.register_message import ReadHoldingRegistersRequest, WriteMultipleRegistersRequest

from mppf.drivers.modbus import ModbusPress
from mppf.drivers.modbus_adapter import RTU_SILENCE_CHARS
from mppf.drivers.url import parse_plc_url
from mppf.model.press import example_press_path, load_press, press_from_dict
from mppf.sim.plc.host import start_simulated_plc
from mppf.sim.serial_pty import BITS_PER_BYTE, wire_time_s

BAUD = 115200
SCAN_S = 0.01


def press_32x32():
    doc = load_press(example_press_path()).to_dict()
    doc["matrix"].update(rows=32, cols=32, pitch_x_mm=150.0, pitch_y_mm=150.0)
    return press_from_dict(doc)


def setpoints(press, k: int):
    """Random setpoints the PLC's own checks take: neighbours within 20 mm of each other, tips 60-70 mm apart."""
    rng = np.random.default_rng(k)
    lower = np.round(rng.uniform(-200.0, -180.0, press.shape), 2)
    upper = np.round(lower + 60.0 + rng.uniform(0.0, 10.0, press.shape), 2)
    return upper, lower


def recorded_upload(plc: ModbusPress, upper, lower) -> tuple[float, list[tuple]]:
    """Time one driver upload and record its requests: ``(function, address, count or words)``."""
    adapter = plc._io
    frames: list[tuple] = []
    call = adapter._call

    def recording(what, function, address, arg, urgent=False):
        frames.append((function, address, arg if function == 3 else list(arg)))
        return call(what, function, address, arg, urgent)

    adapter._call = recording
    try:
        t = time.perf_counter()
        plc.upload(upper, lower)
        return time.perf_counter() - t, frames
    finally:
        adapter._call = call


def bare_replay(client, frames: list[tuple], unit: int) -> None:
    """The driver's frames sent by hand: no checks beyond isError(), no waiting."""
    for function, address, arg in frames:
        if function == 3:
            assert not client.read_holding_registers(address, count=arg, device_id=unit).isError()
        else:
            assert not client.write_registers(address, arg, device_id=unit).isError()


def rtu_frames(frames: list[tuple], unit: int) -> list[tuple[bytes, int]]:
    """RTU request frames (built by pymodbus) and the length of their normal replies."""
    framer = FramerRTU(DecodePDU(False))
    out = []
    for function, address, arg in frames:
        if function == 3:  # FC3 reply: unit, fc, byte count, data, crc
            request = ReadHoldingRegistersRequest(address=address, count=arg, dev_id=unit)
            out.append((framer.buildFrame(request), 5 + 2 * arg))
        else:  # FC16 reply: unit, fc, address, quantity, crc
            request = WriteMultipleRegistersRequest(address=address, registers=arg, dev_id=unit)
            out.append((framer.buildFrame(request), 8))
    return out


def raw_replay(port, frames: list[tuple[bytes, int]], silence_s: float) -> None:
    """Prebuilt frames written and their replies read with exact lengths: the floor of the link."""
    for request, reply_len in frames:
        time.sleep(silence_s)
        port.write(request)
        reply = port.read(reply_len)
        assert len(reply) == reply_len and not reply[1] & 0x80, reply


def rtu_wire_time_s(frames: list[tuple[bytes, int]], baud: int) -> float:
    """Bytes of requests and replies at 11 bits each, plus 3.5 characters of silence before each frame."""
    n_bytes = sum(len(request) + reply_len for request, reply_len in frames)
    silences = 2 * len(frames) * RTU_SILENCE_CHARS * BITS_PER_BYTE / baud
    return wire_time_s(n_bytes, baud) + silences


def tcp_rows(press, grids, repeat: int) -> list[tuple]:
    """Driver upload vs the bare replay of its frames, alternating on one simulated PLC."""
    drv, raw = [], []
    with start_simulated_plc(press, watchdog_s=None, scan_s=SCAN_S) as sim:
        client = ModbusTcpClient("127.0.0.1", port=sim.port, timeout=2.0, retries=0)
        client.connect()
        with ModbusPress(sim.url, press, heartbeat_s=None) as plc:
            for k in range(repeat + 1):
                t_plc, frames = recorded_upload(plc, *grids[k % 4])
                t = time.perf_counter()
                bare_replay(client, frames, 1)
                t_bare = time.perf_counter() - t
                if k:  # the first round warms up
                    drv.append(t_plc)
                    raw.append(t_bare)
        client.close()
    t_drv, t_raw = statistics.median(drv), statistics.median(raw)
    return [("TCP loopback: driver upload (claim, write, read back, validate)", t_drv,
             f"bare pymodbus {t_raw * 1e3:.1f} ms",
             f"{len(frames)} frames; overhead {100 * (t_drv / t_raw - 1):+.1f} % (target <= 25 %; includes the "
             f"waits for the PLC's {SCAN_S * 1e3:.0f} ms scans)")]


def rtu_rows(press, grids, repeat: int) -> list[tuple]:
    """Driver, bare pymodbus and the link's floor in rotating turns on one paced RTU link."""
    rtu, rtu_bare, rtu_raw = [], [], []
    recorded: list[list[tuple]] = []
    with start_simulated_plc(press, rtu=True, baud=BAUD, paced=True, watchdog_s=None, scan_s=SCAN_S) as sim:
        url = parse_plc_url(sim.url)  # a pseudo-terminal refuses parity E: the simulator serves 8N1
        silence_s = RTU_SILENCE_CHARS * url.char_time_s

        def driver(k):
            with ModbusPress(sim.url, press, heartbeat_s=None, timeout_s=3.0) as plc:
                recorded_upload(plc, *grids[k % 4])  # untimed: opens the port, claims
                t, frames = recorded_upload(plc, *grids[(k + 1) % 4])
                rtu.append(t)
                recorded.append(frames)

        def bare(k):
            if not recorded:
                driver(k)
            client = ModbusSerialClient(url.device, baudrate=url.baud, parity=url.parity, stopbits=url.stopbits,
                                        timeout=3.0, retries=0)
            client.connect()
            bare_replay(client, recorded[-1], url.unit)
            t = time.perf_counter()
            bare_replay(client, recorded[-1], url.unit)
            rtu_bare.append(time.perf_counter() - t)
            client.close()

        def floor(k):
            if not recorded:
                driver(k)
            frames = rtu_frames(recorded[-1], url.unit)
            with serial.Serial(url.device, baudrate=url.baud, parity=url.parity, stopbits=url.stopbits,
                               timeout=3.0) as port:
                raw_replay(port, frames, silence_s)
                t = time.perf_counter()
                raw_replay(port, frames, silence_s)
                rtu_raw.append(time.perf_counter() - t)

        runners = [driver, bare, floor]
        for k in range(repeat):  # rounds in rotating order, so that a load change hits all three alike
            for run in runners[k % 3:] + runners[:k % 3]:
                run(k)
    frames = rtu_frames(recorded[-1], url.unit)
    t_wire = rtu_wire_time_s(frames, BAUD)
    rows = []
    for name, times, extra in (("driver upload (claim, write, read back, validate)", rtu, " (target <= 1.10 x)"),
                               ("bare pymodbus, the driver's frames", rtu_bare, ""),
                               ("floor: prebuilt frames, exact-length reads", rtu_raw, "")):
        t = statistics.median(times)
        rows.append((f"RTU {BAUD} baud paced: {name}", t, f"wire time {t_wire * 1e3:.1f} ms",
                     f"{t / t_wire:.3f} x wire time{extra}; best {min(times) / t_wire:.3f} x; "
                     f"{(t - t_wire) / len(frames) * 1e3:.2f} ms/frame beyond the wire ({len(frames)} frames)"))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=15, help="uploads per measurement (TCP)")
    parser.add_argument("--rtu-repeat", type=int, default=6, help="rounds of the three RTU runs (each about 2 s)")
    args = parser.parse_args()
    logging.disable(logging.CRITICAL)
    press = press_32x32()
    grids = [setpoints(press, k) for k in range(4)]
    rows = tcp_rows(press, grids, max(1, args.repeat)) + rtu_rows(press, grids, max(1, args.rtu_repeat))
    print(f"2 x {press.rows} x {press.cols} int32 setpoints = {4 * press.rows * press.cols} registers each way; "
          f"medians of {args.repeat} (TCP) / {args.rtu_repeat} (RTU) uploads; PLC scan {SCAN_S * 1e3:.0f} ms")
    print(f"{'case':<76} {'time (ms)':>10}  {'reference':<26} result")
    for name, t, ref, result in rows:
        print(f"{name:<76} {t * 1e3:>10.1f}  {ref:<26} {result}")


if __name__ == "__main__":
    main()
