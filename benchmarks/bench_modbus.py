"""Benchmark: upload plus read-back of 2 x 32 x 32 int32 setpoints through the driver.

1. Modbus TCP on loopback: :meth:`ModbusPress.upload` (readiness and sequence reads,
   34 FC16 frames of <= 122 registers, 34 FC3 read-back frames of <= 124 registers,
   the CRC + sequence write and the status read) against a bare pymodbus loop sending
   the same frames with no checks. Target: driver overhead at most 25 %.
2. Modbus RTU at 115200 baud through a pseudo-terminal relay that paces bytes at
   the baud rate (:class:`mppf.sim.serial_pty.PtyPair`): the same upload against the
   theoretical wire time of its frames at 11 bits per byte. Target: at most 1.15 x.
   Two references run in turn with the driver on the same link: the bare pymodbus loop,
   and the floor of the link itself (the same frames, prebuilt, written with pyserial and
   their replies read with exact lengths: what the relay, the simulated PLC and the
   machine's scheduling cost with no master overhead at all).

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

from mppf.drivers import codec, regmap as rm
from mppf.drivers.modbus import ModbusPress
from mppf.drivers.url import parse_plc_url
from mppf.planning.press import example_press_path, load_press, press_from_dict
from mppf.sim.plc.host import start_simulated_plc
from mppf.sim.serial_pty import wire_time_s

BAUD = 115200


def press_32x32():
    doc = load_press(example_press_path()).to_dict()
    doc["matrix"].update(rows=32, cols=32, pitch_x_mm=150.0, pitch_y_mm=150.0)
    return press_from_dict(doc)


def setpoints(press, k: int):
    rng = np.random.default_rng(k)
    upper = np.round(rng.uniform(0.0, 200.0, press.shape), 2)
    lower = np.round(rng.uniform(-200.0, -50.0, press.shape), 2)
    return upper, lower


def upload_requests(rmap: rm.RegisterMap, press, upper, lower, seq: int) -> list[tuple]:
    """The frames of ModbusPress.upload: ``("read", address, count)`` / ``("write", address, words)``."""
    status = [rmap[n] for n in ("status_word", "plc_heartbeat")]
    st_addr, st_count = status[0].address, status[1].end - status[0].address
    n = rmap.words_in_use(press.rows, press.cols)
    blocks = {side: codec.encode_int32(codec.mm_to_counts(g.ravel()), "ABCD") for side, g in (("upper", upper), ("lower", lower))}
    out = [("read", st_addr, st_count)] * 2  # readiness, sequence
    for side in ("upper", "lower"):
        out += [("write", start, words)
                for start, words in codec.chunks(rmap[f"{side}_setpoints"].address, blocks[side], rmap.max_write_registers)]
    for side in ("upper", "lower"):
        base = rmap[f"{side}_setpoints"].address
        out += [("read", start, min(rmap.max_read_registers, base + n - start))
                for start in range(base, base + n, rmap.max_read_registers)]
    crc = codec.setpoint_crc32(blocks["upper"], blocks["lower"])
    out.append(("write", rmap["setpoint_crc"].address, codec.encode_uint32([crc], "ABCD") + [seq]))
    out.append(("read", st_addr, st_count))
    return out


def bare_upload(client, rmap: rm.RegisterMap, press, upper, lower, seq: int) -> None:
    """The frames of ModbusPress.upload sent by hand: no checks beyond isError()."""
    for kind, address, arg in upload_requests(rmap, press, upper, lower, seq):
        if kind == "read":
            assert not client.read_holding_registers(address, count=arg).isError()
        else:
            assert not client.write_registers(address, arg).isError()


def rtu_frames(requests: list[tuple], unit: int) -> list[tuple[bytes, int]]:
    """RTU request frames (built by pymodbus) and the length of their normal replies."""
    framer = FramerRTU(DecodePDU(False))
    out = []
    for kind, address, arg in requests:
        if kind == "read":  # FC3 reply: unit, fc, byte count, data, crc
            out.append((framer.buildFrame(ReadHoldingRegistersRequest(address=address, count=arg, dev_id=unit)), 5 + 2 * arg))
        else:  # FC16 reply: unit, fc, address, quantity, crc
            out.append((framer.buildFrame(WriteMultipleRegistersRequest(address=address, registers=arg, dev_id=unit)), 8))
    return out


def raw_upload(port, frames: list[tuple[bytes, int]]) -> None:
    """Prebuilt frames written and their replies read with exact lengths: the floor of the link."""
    for request, reply_len in frames:
        port.write(request)
        reply = port.read(reply_len)
        assert len(reply) == reply_len and not reply[1] & 0x80, reply


def wire_bytes(frames: list[tuple[bytes, int]]) -> int:
    """Bytes on the wire (requests + replies)."""
    return sum(len(request) + reply_len for request, reply_len in frames)


def timed(fn, repeat: int) -> list[float]:
    out = []
    for k in range(repeat):
        t = time.perf_counter()
        fn(k)
        out.append(time.perf_counter() - t)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=15, help="uploads per measurement (TCP)")
    parser.add_argument("--rtu-repeat", type=int, default=6,
                        help="timed RTU uploads for the driver and for the bare loop (each about 2 s)")
    args = parser.parse_args()
    logging.disable(logging.CRITICAL)
    press = press_32x32()
    rmap = rm.load_register_map()
    grids = [setpoints(press, k) for k in range(4)]
    rows = []

    # 1. TCP loopback: driver vs bare pymodbus, alternating on the same simulated PLC
    with start_simulated_plc(press, watchdog_s=None) as sim:
        client = ModbusTcpClient("127.0.0.1", port=sim.port, timeout=2.0, retries=0)
        client.connect()
        drv, raw = [], []
        with ModbusPress(sim.url, press, heartbeat_s=None) as plc:
            for k in range(args.repeat + 1):
                t = time.perf_counter()
                plc.upload(*grids[k % 4])
                t_plc = time.perf_counter() - t
                t = time.perf_counter()
                bare_upload(client, rmap, press, *grids[k % 4], 1000 + k)
                t_bare = time.perf_counter() - t
                if k:  # the first round warms up
                    drv.append(t_plc)
                    raw.append(t_bare)
        client.close()
    t_drv, t_raw = statistics.median(drv), statistics.median(raw)
    rows.append(("TCP loopback: driver upload + read-back", t_drv, f"bare pymodbus {t_raw * 1e3:.1f} ms",
                 f"overhead {100 * (t_drv / t_raw - 1):+.1f} % (target <= 25 %)"))

    # 2. RTU at 115200 baud through the paced pty relay: driver, bare pymodbus and the floor in turn
    #    (a serial port has one master at a time: each opens it, uploads untimed once, then timed)
    n_rtu = max(1, args.rtu_repeat)
    rtu, rtu_bare, rtu_raw = [], [], []
    with start_simulated_plc(press, rtu=True, baud=BAUD, paced=True, watchdog_s=None) as sim:
        url = parse_plc_url(sim.url)  # a pseudo-terminal refuses parity E: the simulator serves 8N1
        frames = [rtu_frames(upload_requests(rmap, press, *grids[j % 4], 3000 + j), url.unit) for j in range(4)]

        def driver(k):
            with ModbusPress(sim.url, press, heartbeat_s=None, timeout_s=3.0) as plc:
                rtu.extend(timed(lambda j: plc.upload(*grids[(k + j) % 4]), 2)[1:])

        def bare(k):
            client = ModbusSerialClient(url.device, baudrate=url.baud, parity=url.parity, stopbits=url.stopbits,
                                        timeout=3.0, retries=0)
            client.connect()
            rtu_bare.extend(timed(lambda j: bare_upload(client, rmap, press, *grids[(k + j) % 4], 2000 + k + j), 2)[1:])
            client.close()

        def floor(k):
            with serial.Serial(url.device, baudrate=url.baud, parity=url.parity, stopbits=url.stopbits,
                               timeout=3.0) as port:
                rtu_raw.extend(timed(lambda j: raw_upload(port, frames[(k + j) % 4]), 2)[1:])

        runners = [driver, bare, floor]
        for k in range(n_rtu):  # rounds in rotating order, so that a load change hits all three alike
            for run in runners[k % 3:] + runners[:k % 3]:
                run(k)
    n_frames = len(frames[0])
    t_wire = wire_time_s(wire_bytes(frames[0]), BAUD)
    for name, times, extra in (
        ("driver upload + read-back", rtu, " (target <= 1.15 x)"),
        ("bare pymodbus, same frames", rtu_bare, ""),
        ("floor: prebuilt frames, exact-length reads", rtu_raw, ""),
    ):
        t = statistics.median(times)
        rows.append((f"RTU {BAUD} baud paced: {name}", t, f"wire time {t_wire * 1e3:.1f} ms",
                     f"{t / t_wire:.3f} x wire time{extra}; best {min(times) / t_wire:.3f} x; "
                     f"{(t - t_wire) / n_frames * 1e3:.1f} ms/frame beyond the wire"))

    print(f"2 x {press.rows} x {press.cols} int32 setpoints = {2 * rmap.words_in_use(press.rows, press.cols)} "
          f"registers each way; medians of {args.repeat} (TCP) / {n_rtu} (RTU) uploads (RTU: {n_frames} frames)")
    print(f"{'case':<68} {'time (ms)':>10}  {'reference':<26} result")
    for name, t, ref, result in rows:
        print(f"{name:<68} {t * 1e3:>10.1f}  {ref:<26} {result}")


if __name__ == "__main__":
    main()
