"""The simulated press PLC: a pymodbus server implementing ``drivers/register_map.toml``.

:class:`SimulatedPlc` is the PLC program (register image, command handling, checks,
watchdog, hydraulic motion, injectable faults) running on an asyncio loop;
:func:`run_simulated_plc` hosts it in a background thread for synchronous callers
(tests, dry runs, ``mppf sim``). See ``docs/simulator.md``.

The PLC's register image is the pymodbus device's own register list: the server's
action hook (called before every request is applied) hands it over, and the PLC scan
writes actual positions and status into it directly on the same event loop.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import threading
import time
from collections.abc import Iterator

import numpy as np
from pymodbus.constants import ExcCodes
from pymodbus.framer import FramerType
from pymodbus.server import ModbusSerialServer, ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from mppf.drivers.regmap import (
    RegisterMap,
    check_word_order,
    counts_to_mm,
    decode_int32,
    decode_uint32,
    encode_int32,
    encode_uint32,
    load_register_map,
    mm_to_counts,
    pack_bits,
    setpoint_crc32,
)
from mppf.core.errors import InputError, LinkError
from mppf.planning.press import PressConfig, example_press_path, load_press
from mppf.sim.faults import FaultSpec
from mppf.sim.hydraulics import Hydraulics
from mppf.sim.serial_pty import PtyPair

MATRICES = ("upper", "lower")
_FC_READ = 3
_FC_WRITE = 16
_MAX_STEPS_PER_SCAN = 50  # coarser steps rather than a scan that falls further and further behind


class _HandlerRecord:
    """Server mixin remembering every connection handler it made (to close them all)."""

    def callback_new_connection(self):
        handler = super().callback_new_connection()
        self.__dict__.setdefault("handlers", []).append(handler)
        return handler


class _TcpServer(_HandlerRecord, ModbusTcpServer):
    pass


class _SerialServer(_HandlerRecord, ModbusSerialServer):
    pass


class SimulatedPlc:
    """The simulated press PLC (runs on an asyncio event loop).

    Parameters
    ----------
    press : PressConfig
        Matrix size, stroke limits (the PLC's own limits), speed, acceleration and
        position tolerance.
    word_order : {"ABCD", "CDAB"}
        Word order of 32-bit registers.
    unit : int
        Modbus unit (device) id; other ids get exception 4 from pymodbus.
    time_scale : float
        Simulated seconds per wall-clock second for motion (50 = 50x faster).
    watchdog_s : float or None
        Wall-clock seconds without a master-heartbeat change after which motion is
        stopped with fault WATCHDOG (None or 0: no watchdog).
    seed : int
        Seed of the measurement noise.
    noise_mm : float
        Standard deviation of the noise on reported actual positions (0: exact).
    tick_s : float
        Wall-clock period of the PLC scan (the motion is integrated in steps of at most
        ``tick_s`` simulated seconds).
    regmap : RegisterMap, optional
        Register map (default: the packaged one).
    """

    def __init__(
        self,
        press: PressConfig,
        *,
        word_order: str = "ABCD",
        unit: int = 1,
        time_scale: float = 1.0,
        watchdog_s: float | None = 1.0,
        seed: int = 0,
        noise_mm: float = 0.0,
        tick_s: float = 0.02,
        regmap: RegisterMap | None = None,
        announce_simulated: bool = True,
    ):
        self.press = press
        # status bit `simulated`: the driver skips the operator's confirmation for a simulator;
        # False makes it pose as a real press (to test the confirmation path)
        self.announce_simulated = bool(announce_simulated)
        self.map = regmap or load_register_map()
        self.map.check_shape(press.rows, press.cols)
        self.word_order = check_word_order(word_order)
        if not 1 <= unit <= 247:
            raise InputError(f"Modbus unit id must be 1..247, got {unit}")
        if not (time_scale > 0 and math.isfinite(time_scale)):
            raise InputError(f"time_scale must be a positive number, got {time_scale}",
                             hint="e.g. 1 (real time) or 50 (fast tests)")
        if watchdog_s is not None and not (watchdog_s >= 0 and math.isfinite(watchdog_s)):
            raise InputError(f"watchdog_s must be a number of seconds >= 0 (0 or None: off), got {watchdog_s}")
        if not tick_s > 0:
            raise InputError(f"tick_s must be positive, got {tick_s}")
        self.unit = unit
        self.time_scale = float(time_scale)
        self.watchdog_s = watchdog_s or None
        self.tick_s = float(tick_s)
        self.noise_mm = float(noise_mm)
        self._rng = np.random.default_rng(seed)
        self._words = self.map.words_in_use(press.rows, press.cols)
        park = np.stack(
            [np.full(press.shape, press.upper.park_mm), np.full(press.shape, press.lower.park_mm)]
        )
        self.hydraulics = Hydraulics(park, press.speed_mm_s, press.accel_mm_s2)
        self._regs: list[int] | None = None
        self._internal = False
        self._server = None
        self._server_factory = None
        self._ticker: asyncio.Task | None = None
        self._tasks: set[asyncio.Task] = set()
        self._dropped = False
        # injected conditions
        self.slow_s = 0.0
        self.estop_pressed = False
        self.frozen = False  # PLC program halted: no scan, the communication still answers
        self._motion_faults: list[tuple[float, str]] = []  # (after simulated s of motion, kind)
        self._drop_after_writes: tuple[int, float] | None = None
        self._stuck_fault_after_s: dict[tuple[int, int, int], float] = {}
        self._power_on()

    # ------------------------------------------------------------------ state ---
    def _power_on(self) -> None:
        """Reset the PLC program state (power-on or restart); punches stay where they are."""
        self.hydraulics.halt()
        self.goal_mm = self.hydraulics.position.copy()
        self.busy = False
        self.fault_code = 0
        self.refusal_code = 0
        self.ack_sequence = 0
        self.motion_sequence = 0
        self.data_valid = False
        self.punch_faults = np.zeros((2, self.press.rows, self.press.cols), dtype=bool)
        self.motion_time_s = 0.0
        self._arrived_at_s: float | None = None
        self.heartbeat = 0
        self._last_master_hb: float | None = None
        self._motion_started_wall = 0.0
        if self.estop_pressed:
            self.fault_code = self.map.fault("ESTOP")
        if self._regs is not None:
            self._write_image()

    def _image(self) -> list[int]:
        """The complete power-on register image."""
        m, p = self.map, self.press
        regs = [0] * m.total_registers

        def put(name, words):
            regs[m[name].address : m[name].address + len(words)] = words

        put("magic", encode_uint32([m.magic], self.word_order))
        put("map_version", [m.version])
        put("rows", [p.rows])
        put("cols", [p.cols])
        for side in MATRICES:
            limits = getattr(p, side)
            put(f"{side}_min", encode_int32(mm_to_counts([limits.min_mm], m.count_mm), self.word_order))
            put(f"{side}_max", encode_int32(mm_to_counts([limits.max_mm], m.count_mm), self.word_order))
        for k, side in enumerate(MATRICES):
            put(f"{side}_setpoints", encode_int32(mm_to_counts(self.goal_mm[k].ravel(), m.count_mm), self.word_order))
        return regs

    def _write_image(self) -> None:
        image = self._image()
        self._regs[: len(image)] = image  # pymodbus keeps one guard register past the end
        self._publish()

    def _get(self, name: str) -> list[int]:
        f = self.map[name]
        return self._regs[f.address : f.end]

    def _set(self, name: str, words: list[int]) -> None:
        a = self.map[name].address
        self._regs[a : a + len(words)] = words

    def _setpoint_words(self, side: str) -> list[int]:
        a = self.map[f"{side}_setpoints"].address
        return self._regs[a : a + self._words]

    def _setpoints_mm(self) -> np.ndarray:
        """(2, rows, cols) setpoints currently in the registers."""
        return np.stack(
            [
                counts_to_mm(decode_int32(self._setpoint_words(side), self.word_order), self.map.count_mm).reshape(
                    self.press.shape
                )
                for side in MATRICES
            ]
        )

    def _status_flags(self) -> dict[str, bool]:
        fault = self.fault_code != 0
        in_position = (
            not self.busy
            and bool(np.all(np.abs(self.hydraulics.position - self.goal_mm) <= self.press.position_tolerance_mm))
        )
        now = time.monotonic()
        remote = self._last_master_hb is not None and (
            self.watchdog_s is None or now - self._last_master_hb <= self.watchdog_s
        )
        return {
            "ready": not (self.busy or fault or self.estop_pressed),
            "busy": self.busy,
            "in_position": in_position,
            "fault": fault,
            "estop": self.estop_pressed,
            "remote": remote,
            "data_valid": self.data_valid,
            "simulated": self.announce_simulated,
        }

    def _publish(self) -> None:
        """Write actual positions, fault bits and status into the register image."""
        actual = self.hydraulics.position
        if self.noise_mm > 0:
            actual = actual + self._rng.normal(0.0, self.noise_mm, actual.shape)
        for k, side in enumerate(MATRICES):
            self._set(f"{side}_actuals", encode_int32(mm_to_counts(actual[k].ravel(), self.map.count_mm), self.word_order))
        self._publish_status()

    def _publish_status(self) -> None:
        """Write fault bits, status word, codes, sequences and heartbeat (cheap: after each write)."""
        for k, side in enumerate(MATRICES):
            self._set(f"{side}_fault_bits", pack_bits(self.punch_faults[k].ravel()))
        self._set("status_word", [self.map.status_word(**self._status_flags())])
        self._set("fault_code", [self.fault_code])
        self._set("refusal_code", [self.refusal_code])
        self._set("acknowledged_sequence", [self.ack_sequence])
        self._set("motion_sequence", [self.motion_sequence])
        self._set("plc_heartbeat", [self.heartbeat])

    # ----------------------------------------------------------------- checks ---
    def _crc_ok(self) -> bool:
        crc = setpoint_crc32(self._setpoint_words("upper"), self._setpoint_words("lower"))
        return int(decode_uint32(self._get("setpoint_crc"), self.word_order)[0]) == crc

    def _limits_ok(self) -> bool:
        sp = self._setpoints_mm()
        for k, side in enumerate(MATRICES):
            lim = getattr(self.press, side)
            lo = mm_to_counts(lim.min_mm, self.map.count_mm) * self.map.count_mm
            hi = mm_to_counts(lim.max_mm, self.map.count_mm) * self.map.count_mm
            if np.any(sp[k] < lo - 1e-9) or np.any(sp[k] > hi + 1e-9):
                return False
        return True

    def _latch(self, name: str, *, halt: bool = True) -> None:
        """Latch fault ``name`` and stop the punches (at once, or decelerating)."""
        if self.fault_code == 0:
            self.fault_code = self.map.fault(name)
        if halt:
            self.hydraulics.halt()
        else:
            self.hydraulics.stop()

    # ------------------------------------------------------------- the action ---
    async def _action(self, function_code, start, address, count, registers, set_values):
        """pymodbus action hook: runs before every request is applied."""
        if self._regs is None:
            if start != 0:
                raise RuntimeError(f"register block starts at {start}, expected 0")
            self._regs = registers
        if self._internal:
            return None
        if self.slow_s:
            await asyncio.sleep(self.slow_s)
        if not set_values:
            return None
        if self.frozen:
            return None  # a halted program: the write lands in memory, no logic acts on it
        if self._drop_after_writes is not None:
            left, duration = self._drop_after_writes
            if left <= 1:
                self._drop_after_writes = None
                await self.drop(duration)  # the link is gone: this reply is never sent
                return ExcCodes.DEVICE_FAILURE
            self._drop_after_writes = (left - 1, duration)
        return self._write(address, list(set_values))

    def _write(self, address: int, values: list[int]) -> ExcCodes | None:
        """Handle a master write of ``values`` at ``address`` (already range-checked)."""
        m = self.map
        end = address + len(values)
        touched = {f.name: f for f in m.fields.values() if f.address < end and address < f.end}
        covered = sum(min(end, f.end) - max(address, f.address) for f in touched.values())
        if covered < len(values) or any(not f.writable for f in touched.values()):  # a gap or a read-only register
            self.refusal_code = m.fault("READ_ONLY")
            self._publish_status()
            return ExcCodes(m.exceptions["read_only"])
        old = self._regs[address:end]
        old_hb = self._get("master_heartbeat")[0]
        self._regs[address:end] = values
        if "master_heartbeat" in touched and self._get("master_heartbeat")[0] != old_hb:
            self._last_master_hb = time.monotonic()
        if "upper_setpoints" in touched or "lower_setpoints" in touched:
            self.data_valid = False
        refusal = None
        if "job_sequence" in touched:
            refusal = self._validate()
        if refusal is None and "command" in touched:
            refusal = self._command(self._get("command")[0], self._get("command_arg")[0])
        if refusal is not None:
            self._regs[address:end] = old
            self.refusal_code = m.fault(refusal)
            self._publish_status()
            return ExcCodes(m.exceptions["refused"])
        self._publish_status()
        return None

    def _validate(self) -> str | None:
        """The master wrote ``job_sequence``: check CRC and limits, acknowledge."""
        sequence = self._get("job_sequence")[0]
        if sequence == 0:
            return "SEQUENCE_MISMATCH"
        if not self._crc_ok():
            return "CRC_MISMATCH"
        if not self._limits_ok():
            return "LIMIT"
        self.ack_sequence = sequence
        self.data_valid = True
        return None

    def _command(self, code: int, arg: int) -> str | None:
        m = self.map
        if code == m.command("STOP"):
            self.hydraulics.stop()
            self._motion_faults = []
        elif code == m.command("RESET"):
            if self.estop_pressed:
                return "ESTOP_ACTIVE"
            self.fault_code = 0
            self.punch_faults[:] = False
        elif code == m.command("GO"):
            refusal = self._go_refusal(arg)
            if refusal is not None:
                return refusal
            if not (self.busy and arg == self.motion_sequence):  # a repeated GO does nothing
                self._start_motion(arg)
        elif code != m.commands.get("NONE", 0):
            return "BAD_COMMAND"
        self.refusal_code = 0
        return None

    def _go_refusal(self, arg: int) -> str | None:
        if self.estop_pressed:
            return "ESTOP_ACTIVE"
        if self.fault_code:
            return "FAULT_ACTIVE"
        if self.busy:
            return None if arg == self.motion_sequence else "BUSY"
        if not self._crc_ok():
            return "CRC_MISMATCH"
        if not self._limits_ok():
            return "LIMIT"
        if arg == 0 or arg != self.ack_sequence:
            return "SEQUENCE_MISMATCH"
        if not self.data_valid:
            return "NOT_VALIDATED"
        return None

    def _start_motion(self, sequence: int) -> None:
        self.goal_mm = self._setpoints_mm()
        self.hydraulics.move_to(self.goal_mm)
        self.motion_sequence = sequence
        self.busy = True
        self.motion_time_s = 0.0
        self._arrived_at_s = None
        self._motion_started_wall = time.monotonic()

    # --------------------------------------------------------------- the scan ---
    def _scan(self, wall_dt_s: float) -> None:
        """One PLC scan: integrate motion, run timers and faults, publish."""
        sim_dt = wall_dt_s * self.time_scale
        steps = min(max(1, int(np.ceil(sim_dt / self.tick_s))), _MAX_STEPS_PER_SCAN)
        for _ in range(steps):
            self._step(sim_dt / steps)
            if self.frozen:  # the program halted in this step: this scan publishes its last image
                break
        self._check_watchdog()
        self.heartbeat = (self.heartbeat + 1) & 0xFFFF
        self._publish()

    def _step(self, dt_s: float) -> None:
        """Advance the motion and its timers by ``dt_s`` simulated seconds."""
        self.hydraulics.step(dt_s)
        if not self.busy:
            return
        self.motion_time_s += dt_s
        for after_s, kind in list(self._motion_faults):
            if self.motion_time_s >= after_s:
                self._motion_faults.remove((after_s, kind))
                self._trigger(kind)
        if self.frozen:
            return
        self._check_stuck()
        if not self.hydraulics.moving and not self._stuck_pending():
            self.busy = False

    def _check_watchdog(self) -> None:
        if self.watchdog_s is None or not self.busy or self.fault_code:
            return
        last = max(self._last_master_hb or 0.0, self._motion_started_wall)
        if time.monotonic() - last > self.watchdog_s:
            self._latch("WATCHDOG", halt=False)

    def _stuck_short(self) -> np.ndarray:
        """(2, rows, cols) bool: stuck punches short of their goal."""
        stuck = ~np.isnan(self.hydraulics.stuck_fraction)
        off = np.abs(self.hydraulics.position - self.goal_mm) > self.press.position_tolerance_mm
        return stuck & off

    def _stuck_pending(self) -> bool:
        """A stuck punch whose fault timer is still running keeps the PLC busy."""
        if self.fault_code:
            return False
        return any(self._stuck_short()[idx] for idx in self._stuck_fault_after_s)

    def _check_stuck(self) -> None:
        if self.fault_code or not self._stuck_fault_after_s or self.hydraulics.moving:
            return
        if self._arrived_at_s is None:
            self._arrived_at_s = self.motion_time_s
        short = self._stuck_short()
        for idx, after_s in self._stuck_fault_after_s.items():
            if short[idx] and self.motion_time_s - self._arrived_at_s >= after_s:
                self.punch_faults[idx] = True
                self._latch("STUCK_PUNCH")

    def _trigger(self, kind: str) -> None:
        if kind == "freeze":
            self.frozen = True
            self.hydraulics.halt()  # outputs off: the valves close
        elif kind == "estop":
            self.estop_pressed = True
            self._latch("ESTOP")
        elif kind == "overpressure":
            self._latch("OVERPRESSURE")

    async def _run_scan(self) -> None:
        last = time.monotonic()
        while True:
            await asyncio.sleep(self.tick_s)
            now = time.monotonic()
            if not self.frozen:
                self._scan(now - last)
            last = now

    # ---------------------------------------------------------------- faults ---
    def inject(self, kind: str, **params) -> None:
        """Inject a fault (call on the PLC's event loop; see docs/simulator.md).

        Parameters
        ----------
        kind : {"stuck", "estop", "overpressure", "freeze", "slow", "drop", "restart"}
        **params
            stuck: ``matrix`` ("upper"/"lower"), ``row``, ``col``, ``percent`` (of each
            move done before it sticks, default 50), ``fault_after_s`` (simulated s after
            the other punches arrived until fault STUCK_PUNCH and the punch's fault bit;
            None: no fault, motion simply ends short). estop / overpressure / freeze:
            ``after_s`` (simulated s of motion of the next or current GO; None: now).
            slow: ``delay_ms``. drop: ``duration_s`` (2.0), ``after_s`` (wall s; None:
            now), ``after_writes`` (drop on the n-th master write, which is not applied).
            restart: ``after_s`` (wall s; None: now), ``downtime_s`` (0.3).

        Raises
        ------
        InputError
            Unknown fault or bad parameters.
        """
        try:
            self._inject(kind, **params)
        except TypeError as exc:
            raise InputError(f"fault {kind!r}: {exc}", hint="see docs/simulator.md for the parameters") from None
        if self._regs is not None:
            self._publish()

    def _inject(self, kind, **params) -> None:
        if kind == "stuck":
            self._inject_stuck(**params)
        elif kind in ("estop", "overpressure", "freeze"):
            self._inject_timed(kind, **params)
        elif kind == "slow":
            self._inject_slow(**params)
        elif kind == "drop":
            self._inject_drop(**params)
        elif kind == "restart":
            self._inject_restart(**params)
        else:
            raise InputError(
                f"unknown fault {kind!r}",
                hint="known faults: stuck, estop, overpressure, freeze, slow, drop, restart",
            )

    def _inject_stuck(self, matrix, row, col, percent=50.0, fault_after_s=None) -> None:
        if matrix not in MATRICES:
            raise InputError(f"stuck punch: matrix must be 'upper' or 'lower', got {matrix!r}")
        if not (0 <= row < self.press.rows and 0 <= col < self.press.cols):
            raise InputError(
                f"stuck punch: row {row}, col {col} outside the {self.press.rows} x {self.press.cols} matrix",
                hint="rows and columns count from 0",
            )
        if not 0 <= percent <= 100:
            raise InputError(f"stuck punch: percent must be 0..100, got {percent}")
        idx = (MATRICES.index(matrix), int(row), int(col))
        self.hydraulics.set_stuck(idx, percent / 100.0)
        if fault_after_s is not None:
            self._stuck_fault_after_s[idx] = float(fault_after_s)

    def _inject_timed(self, kind, after_s=None) -> None:
        if after_s is None:
            self._trigger(kind)
        else:
            self._motion_faults.append((float(after_s), kind))

    def _inject_slow(self, delay_ms) -> None:
        if not delay_ms >= 0:
            raise InputError(f"slow replies: delay_ms must be >= 0, got {delay_ms}")
        self.slow_s = delay_ms / 1000.0

    def _inject_drop(self, duration_s=2.0, after_s=None, after_writes=None) -> None:
        if not duration_s >= 0:
            raise InputError(f"dropped connection: duration_s must be >= 0, got {duration_s}")
        if after_writes is not None:
            self._drop_after_writes = (int(after_writes), float(duration_s))
        else:
            self._spawn(self._drop(duration_s, delay_s=after_s or 0.0))

    def _inject_restart(self, after_s=None, downtime_s=0.3) -> None:
        self._spawn(self._restart(delay_s=after_s or 0.0, downtime_s=downtime_s))

    def clear_faults(self) -> None:
        """Remove every injected condition (stuck punches, slow replies, pending
        triggers, a pressed e-stop). Latched faults stay until the master sends RESET."""
        self.hydraulics.free_all()
        self._stuck_fault_after_s.clear()
        self._motion_faults = []
        self._drop_after_writes = None
        self.slow_s = 0.0
        self.estop_pressed = False
        self.frozen = False
        if self._regs is not None:
            self._publish()

    def _spawn(self, coro) -> None:
        task = asyncio.get_running_loop().create_task(coro)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    async def drop(self, duration_s: float) -> None:
        """Close every connection now and answer nothing for ``duration_s`` seconds."""
        if self._dropped:
            return
        self._dropped = True
        await self._shutdown_server()
        self._spawn(self._relisten(duration_s))

    async def _shutdown_server(self) -> None:
        """Stop listening and close every connection, also one accepted while closing."""
        server = self._server
        await asyncio.sleep(0.02)  # connections in the listen backlog are accepted first
        await server.shutdown()
        await asyncio.sleep(0.02)  # an accept in flight completes
        for handler in server.__dict__.get("handlers", []):
            if handler.transport is not None:
                handler.transport.close()
        await asyncio.sleep(0.01)  # closing transports release their sockets on the next loop turns

    async def _relisten(self, after_s: float) -> None:
        try:
            await asyncio.sleep(after_s)
            for _ in range(50):  # the port may take a moment to be free again
                try:
                    await self._listen()
                    return
                except (OSError, RuntimeError):
                    await asyncio.sleep(0.1)
            await self._listen()
        finally:
            self._dropped = False

    async def restart(self, downtime_s: float = 0.3) -> None:
        """Restart now: program state to power-on, connections dropped for ``downtime_s``."""
        self.frozen = False
        self._power_on()
        await self.drop(downtime_s)

    async def _drop(self, duration_s: float, delay_s: float = 0.0) -> None:
        await asyncio.sleep(delay_s)
        await self.drop(duration_s)

    async def _restart(self, delay_s: float, downtime_s: float) -> None:
        await asyncio.sleep(delay_s)
        await self.restart(downtime_s)

    # ---------------------------------------------------------------- serving ---
    def _device(self) -> SimDevice:
        return SimDevice(
            id=self.unit,
            simdata=[SimData(0, count=self.map.total_registers, values=0, datatype=DataType.REGISTERS)],
            action=self._action,
        )

    async def _listen(self) -> None:
        server = self._server_factory()
        await server.serve_forever(background=True)
        self._internal = True
        try:
            if self._regs is None:
                await server.async_setValues(self.unit, _FC_WRITE, 0, self._image())
            else:  # a new server after a drop: carry the image over
                await server.async_setValues(self.unit, _FC_WRITE, 0, self._regs[: self.map.total_registers])
                self._regs = None
                await server.async_getValues(self.unit, _FC_READ, 0, 1)
        finally:
            self._internal = False
        self._server = server
        self._publish()

    async def start_tcp(self, host: str = "127.0.0.1", port: int = 0) -> int:
        """Serve Modbus TCP on ``host:port`` (0: a free port); return the port."""
        address = [host, port]
        self._server_factory = lambda: _TcpServer(self._device(), address=tuple(address))
        await self._listen()
        address[1] = self._server.transport.sockets[0].getsockname()[1]  # the port bound
        self._ticker = asyncio.get_running_loop().create_task(self._run_scan())
        return address[1]

    async def start_rtu(self, port: str, *, baud: int = 115200, parity: str = "E", stopbits: int = 1) -> None:
        """Serve Modbus RTU on serial device ``port``."""
        self._server_factory = lambda: _SerialServer(
            self._device(),
            framer=FramerType.RTU,
            port=port,
            baudrate=baud,
            parity=parity,
            stopbits=stopbits,
            bytesize=8,
        )
        await self._listen()
        self._ticker = asyncio.get_running_loop().create_task(self._run_scan())

    async def stop(self) -> None:
        """Stop the scan and the server."""
        for task in [self._ticker, *self._tasks]:
            if task is not None:
                task.cancel()
        for task in [self._ticker, *self._tasks]:
            if task is not None:
                with contextlib.suppress(asyncio.CancelledError):
                    await task
        if self._server is not None:
            await self._shutdown_server()

    # ---------------------------------------------------------------- reading ---
    def actual_positions_mm(self) -> tuple[np.ndarray, np.ndarray]:
        """Actual tip heights (upper, lower), each (rows, cols) mm, without noise."""
        pos = self.hydraulics.position
        return pos[0].copy(), pos[1].copy()

    def setpoints_mm(self) -> tuple[np.ndarray, np.ndarray]:
        """Setpoints in the registers (upper, lower), each (rows, cols) mm."""
        sp = self._setpoints_mm()
        return sp[0], sp[1]

    def status_bits(self) -> dict[str, bool]:
        """Status-word flags by name."""
        return self._status_flags()


# ----------------------------------------------------------------------------------
# Thread host for synchronous callers
# ----------------------------------------------------------------------------------
class SimHandle:
    """A running simulated PLC, hosted in a background thread.

    Attributes
    ----------
    url : str
        ``tcp://127.0.0.1:PORT?unit=1`` or ``rtu:///dev/pts/N?baud=115200&parity=E&unit=1``.
    plc : SimulatedPlc
        The PLC object (touch it only through the methods below).
    port : int or None
        TCP port.
    serial_port : str or None
        The client's end of the RTU pseudo-terminal pair (or the serial device).
    """

    def __init__(self, plc: SimulatedPlc):
        self.plc = plc
        self.url = ""
        self.port: int | None = None
        self.serial_port: str | None = None
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, daemon=True, name="simulated-plc")
        self._pty: PtyPair | None = None
        self._stopped = False

    def _call(self, fn, *args, **kwargs):
        """Run ``fn`` on the PLC's loop and return its result (exceptions re-raised)."""

        async def run():
            result = fn(*args, **kwargs)
            if asyncio.iscoroutine(result):
                result = await result
            return result

        if self._stopped:
            raise LinkError("the simulated PLC has been stopped")
        return asyncio.run_coroutine_threadsafe(run(), self._loop).result(timeout=30)

    def inject(self, kind: str, **params) -> None:
        """Inject a fault (see :meth:`SimulatedPlc.inject`)."""
        self._call(self.plc.inject, kind, **params)

    def inject_spec(self, spec: FaultSpec) -> None:
        """Inject a parsed ``--fault`` spec."""
        self.inject(spec.kind, **spec.params)

    def clear_faults(self) -> None:
        """Remove injected conditions (see :meth:`SimulatedPlc.clear_faults`)."""
        self._call(self.plc.clear_faults)

    def release_estop(self) -> None:
        """Release a pressed e-stop (the ESTOP fault stays latched until RESET)."""

        def release():
            self.plc.estop_pressed = False
            self.plc._publish()

        self._call(release)

    def actual_positions_mm(self) -> tuple[np.ndarray, np.ndarray]:
        """Actual tip heights (upper, lower), each (rows, cols) mm."""
        return self._call(self.plc.actual_positions_mm)

    def setpoints_mm(self) -> tuple[np.ndarray, np.ndarray]:
        """Setpoints in the registers (upper, lower), each (rows, cols) mm."""
        return self._call(self.plc.setpoints_mm)

    def status_bits(self) -> dict[str, bool]:
        """Status-word flags by name."""
        return self._call(self.plc.status_bits)

    def fault_code(self) -> int:
        """The latched fault code (0 = none)."""
        return self._call(lambda: self.plc.fault_code)

    def refusal_code(self) -> int:
        """The reason of the last refused write (0 = none)."""
        return self._call(lambda: self.plc.refusal_code)

    def restart(self, downtime_s: float = 0.3) -> None:
        """Restart the PLC now: registers to power-on state, connections dropped for ``downtime_s``."""
        self._call(self.plc.restart, downtime_s)

    def drop_connections(self, duration_s: float) -> None:
        """Close every connection now and answer nothing for ``duration_s`` seconds."""
        self._call(self.plc.drop, duration_s)

    def write_foreign_setpoint(self, matrix: str, row: int, col: int, value_mm: float) -> None:
        """Change one setpoint register as a foreign master would (no CRC update)."""

        def write():
            plc = self.plc
            if matrix not in MATRICES:
                raise InputError(f"matrix must be 'upper' or 'lower', got {matrix!r}")
            field = plc.map[f"{matrix}_setpoints"]
            index = plc.map.punch_index(row, col, plc.press.cols)
            words = encode_int32(mm_to_counts([value_mm], plc.map.count_mm), plc.word_order)
            return plc._write(field.address + 2 * index, words)

        code = self._call(write)
        if code is not None:
            raise LinkError(f"the simulated PLC refused the foreign write (exception {int(code)})")

    def wait_idle(self, timeout_s: float = 10.0) -> dict[str, bool]:
        """Wait until the PLC is not busy; return the status flags."""
        deadline = time.monotonic() + timeout_s
        while True:
            flags = self.status_bits()
            if not flags["busy"] or time.monotonic() > deadline:
                return flags
            time.sleep(0.01)

    def stop(self) -> None:
        """Stop the server and the thread (idempotent)."""
        if self._stopped:
            return
        try:
            asyncio.run_coroutine_threadsafe(self.plc.stop(), self._loop).result(timeout=10)
        finally:
            self._stopped = True
            self._loop.call_soon_threadsafe(self._loop.stop)
            self._thread.join(timeout=10)
            self._loop.close()
            if self._pty is not None:
                self._pty.close()

    def __enter__(self) -> SimHandle:
        return self

    def __exit__(self, *exc) -> None:
        self.stop()


def start_simulated_plc(
    press: PressConfig | None = None,
    *,
    host: str = "127.0.0.1",
    port: int = 0,
    rtu: bool = False,
    rtu_port: str | None = None,
    baud: int = 115200,
    parity: str = "E",
    paced: bool = False,
    faults: list[FaultSpec] = (),
    **options,
) -> SimHandle:
    """Start a simulated PLC in a background thread; the caller must ``stop()`` it.

    Parameters
    ----------
    press : PressConfig, optional
        Default: the bundled example press.
    host, port : str, int
        TCP address (port 0: a free port). Used unless ``rtu`` or ``rtu_port``.
    rtu : bool
        Serve RTU on a new pseudo-terminal pair (:class:`PtyPair`); ``url`` names the
        client's end.
    rtu_port : str, optional
        Serve RTU on this serial device instead.
    baud, parity : int, str
        Serial settings (RTU). On a pseudo-terminal pair whose kernel refuses parity
        settings (:attr:`PtyPair.supports_parity`), parity N is used instead; ``url``
        always states the parity in use.
    paced : bool
        Pace the pseudo-terminal relay at ``baud`` (11 bits/byte).
    faults : list of FaultSpec
        Faults to inject at start.
    **options
        Keyword arguments of :class:`SimulatedPlc` (``word_order``, ``unit``,
        ``time_scale``, ``watchdog_s``, ``seed``, ``noise_mm``, ``tick_s``).
    """
    press = press or load_press(example_press_path())
    if parity not in ("N", "E", "O"):
        raise InputError(f"parity must be N, E or O, got {parity!r}")
    plc = SimulatedPlc(press, **options)
    handle = SimHandle(plc)
    handle._thread.start()
    try:
        if rtu or rtu_port:
            serve_on = rtu_port
            if rtu_port is None:
                handle._pty = PtyPair(baud=baud if paced else None)
                serve_on, handle.serial_port = handle._pty.port_a, handle._pty.port_b
                if not handle._pty.supports_parity:
                    parity = "N"  # this kernel refuses parity on pseudo-terminals
            else:
                handle.serial_port = rtu_port
            with _start_failure(f"serial device {serve_on}", "give an existing serial device, or 'pty'"):
                asyncio.run_coroutine_threadsafe(plc.start_rtu(serve_on, baud=baud, parity=parity),
                                                 handle._loop).result(10)
            handle.url = f"rtu://{handle.serial_port}?baud={baud}&parity={parity}&unit={plc.unit}"
        else:
            with _start_failure(f"{host}:{port}", "choose another --port (0: a free one) or a local --host; "
                                "is another simulator already running there?"):
                handle.port = asyncio.run_coroutine_threadsafe(plc.start_tcp(host, port), handle._loop).result(10)
            handle.url = f"tcp://{host}:{handle.port}?unit={plc.unit}"
        for spec in faults:
            handle.inject_spec(spec)
    except BaseException:
        handle.stop()
        raise
    return handle


class _LogCapture(logging.Handler):
    """Keeps the messages pymodbus logs while a server starts (the reason of a failure)."""

    def __init__(self):
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


@contextlib.contextmanager
def _start_failure(where: str, hint: str) -> Iterator[None]:
    """Turn pymodbus's "could not start" (a RuntimeError; the reason only logged) into an InputError."""
    log = logging.getLogger("pymodbus")
    capture = _LogCapture()
    log.addHandler(capture)
    propagate, log.propagate = log.propagate, False  # the reason goes into our message, not on stderr
    try:
        yield
    except RuntimeError as exc:
        # pymodbus logs "Repeating...." instead of a message identical to its previous one
        reason = "; ".join(m for m in capture.messages if not m.startswith("Repeating")) or f"pymodbus: {exc}"

        raise InputError(f"the simulated PLC cannot serve on {where}: {reason}", hint=hint) from None
    finally:
        log.removeHandler(capture)
        log.propagate = propagate


@contextlib.contextmanager
def run_simulated_plc(press: PressConfig | None = None, **kwargs) -> Iterator[SimHandle]:
    """Context manager around :func:`start_simulated_plc` (stops the PLC on exit)."""
    handle = start_simulated_plc(press, **kwargs)
    try:
        yield handle
    finally:
        handle.stop()
