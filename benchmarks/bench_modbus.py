"""Benchmark: upload plus read-back of 2 x 32 x 32 int32 setpoints through the driver.

1. Modbus TCP on loopback: :meth:`ModbusPress.upload` (readiness and sequence reads,
   34 FC16 frames of <= 122 registers, 34 FC3 read-back frames of <= 124 registers,
   the CRC + sequence write and the status read) against a bare pymodbus loop sending
   the same frames with no checks. Target: driver overhead at most 25 %.
2. Modbus RTU at 115200 baud through a pseudo-terminal relay that paces bytes at
   the baud rate (:class:`mppf.sim.serial_pty.PtyPair`): the same upload against the
   theoretical wire time of its frames at 11 bits per byte. Target: at most 1.15 x.

Run: ``python benchmarks/bench_modbus.py [--repeat N] [--rtu-repeat M]``. The bare loop imports pymodbus
directly on purpose: it is the reference the adapter is measured against.
"""

from __future__ import annotations

import argparse
import logging
import statistics
import time

import numpy as np
from pymodbus.client import ModbusSerialClient, ModbusTcpClient

from mppf.drivers import regmap as rm
from mppf.drivers.modbus import ModbusPress
from mppf.drivers.url import parse_plc_url
from mppf.press import example_press_path, load_press, press_from_dict
from mppf.sim.plc import start_simulated_plc
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


def bare_upload(client, rmap: rm.RegisterMap, press, upper, lower, seq: int) -> None:
    """The frames of ModbusPress.upload sent by hand: no checks beyond isError()."""
    status = [rmap[n] for n in ("status_word", "plc_heartbeat")]
    st_addr, st_count = status[0].address, status[1].end - status[0].address
    n = rmap.words_in_use(press.rows, press.cols)
    blocks = {side: rm.encode_int32(rm.mm_to_counts(g.ravel()), "ABCD") for side, g in (("upper", upper), ("lower", lower))}
    for _ in range(2):  # readiness, sequence
        assert not client.read_holding_registers(st_addr, count=st_count).isError()
    for side in ("upper", "lower"):
        for start, words in rm.chunks(rmap[f"{side}_setpoints"].address, blocks[side], rmap.max_write_registers):
            assert not client.write_registers(start, words).isError()
    for side in ("upper", "lower"):
        base = rmap[f"{side}_setpoints"].address
        for start in range(base, base + n, rmap.max_read_registers):
            count = min(rmap.max_read_registers, base + n - start)
            assert not client.read_holding_registers(start, count=count).isError()
    crc = rm.setpoint_crc32(blocks["upper"], blocks["lower"])
    assert not client.write_registers(rmap["setpoint_crc"].address, rm.encode_uint32([crc], "ABCD") + [seq]).isError()
    assert not client.read_holding_registers(st_addr, count=st_count).isError()


def rtu_wire_bytes(rmap: rm.RegisterMap, press) -> int:
    """Bytes on the wire (requests + replies) of one driver upload in RTU framing."""
    n = rmap.words_in_use(press.rows, press.cols)
    status_regs = rmap["plc_heartbeat"].end - rmap["status_word"].address
    total = 0

    def read(count):  # FC3: request 8 bytes; reply addr, fc, byte count, data, crc
        return 8 + 5 + 2 * count

    def write(count):  # FC16: request addr fc start qty bytecount data crc; reply 8 bytes
        return 9 + 2 * count + 8

    total += 3 * read(status_regs)
    for _ in range(2):
        total += sum(write(len(w)) for _, w in rm.chunks(0, [0] * n, rmap.max_write_registers))
        total += sum(read(min(rmap.max_read_registers, n - i)) for i in range(0, n, rmap.max_read_registers))
    total += write(3)
    return total


def rtu_frames(rmap: rm.RegisterMap, press) -> int:
    """Request/reply pairs of one driver upload (3 status reads, the blocks both ways, the CRC write)."""
    n = rmap.words_in_use(press.rows, press.cols)
    per_side = len(list(rm.chunks(0, [0] * n, rmap.max_write_registers))) + -(-n // rmap.max_read_registers)
    return 3 + 2 * per_side + 1


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
    parser.add_argument("--rtu-repeat", type=int, default=3,
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

    # 2. RTU at 115200 baud through the paced pty relay: driver and bare pymodbus in turn
    #    (a serial port has one master at a time: each opens it, uploads untimed once, then timed)
    n_rtu = max(1, args.rtu_repeat)
    rtu, rtu_raw = [], []
    with start_simulated_plc(press, rtu=True, baud=BAUD, paced=True, watchdog_s=None) as sim:
        url = parse_plc_url(sim.url)  # a pseudo-terminal refuses parity E: the simulator serves 8N1
        for k in range(n_rtu):
            with ModbusPress(sim.url, press, heartbeat_s=None, timeout_s=3.0) as plc:
                rtu += timed(lambda j: plc.upload(*grids[(k + j) % 4]), 2)[1:]
            client = ModbusSerialClient(url.device, baudrate=url.baud, parity=url.parity, stopbits=url.stopbits,
                                        timeout=3.0, retries=0)
            client.connect()
            rtu_raw += timed(lambda j: bare_upload(client, rmap, press, *grids[(k + j) % 4], 2000 + 2 * k + j), 2)[1:]
            client.close()
    t_rtu, t_rtu_raw = statistics.median(rtu), statistics.median(rtu_raw)
    t_wire = wire_time_s(rtu_wire_bytes(rmap, press), BAUD)
    n_frames = rtu_frames(rmap, press)
    rows.append(("RTU 115200 baud paced: driver upload + read-back", t_rtu, f"wire time {t_wire * 1e3:.1f} ms",
                 f"{t_rtu / t_wire:.3f} x wire time (target <= 1.15 x); best {min(rtu) / t_wire:.3f} x; "
                 f"{(t_rtu - t_wire) / n_frames * 1e3:.1f} ms/frame beyond the wire"))
    rows.append(("RTU 115200 baud paced: bare pymodbus, same frames", t_rtu_raw, f"wire time {t_wire * 1e3:.1f} ms",
                 f"{t_rtu_raw / t_wire:.3f} x wire time; best {min(rtu_raw) / t_wire:.3f} x; "
                 f"driver {100 * (t_rtu / t_rtu_raw - 1):+.1f} %"))

    print(f"2 x {press.rows} x {press.cols} int32 setpoints = {2 * rmap.words_in_use(press.rows, press.cols)} "
          f"registers each way; medians of {args.repeat} (TCP) / {n_rtu} (RTU) uploads")
    print(f"{'case':<52} {'time (ms)':>10}  {'reference':<26} result")
    for name, t, ref, result in rows:
        print(f"{name:<52} {t * 1e3:>10.1f}  {ref:<26} {result}")


if __name__ == "__main__":
    main()
