"""Modbus hosting of the simulated PLC's program: a pymodbus server (TCP or RTU) on an asyncio loop.

:class:`PlcServer` serves a :class:`mppf.sim.plc.program.PlcProgram` the way the
communication module of a real PLC serves its program (pymodbus 3.16: the datastore
hooks are gone; the simulator data model's action hook is the way to act on requests):

- the device is a pymodbus ``SimDevice`` with one register block; its action hook (called
  before every request is applied) hands the block's register list to the program, which
  then works on it directly (:meth:`PlcProgram.adopt_image`). pymodbus stores a master's
  write in that list at once and answers it; the program sees it in its next scan, never
  inside the request. The only exception reply is pymodbus's own for an address outside
  the map (ILLEGAL DATA ADDRESS);
- a scan task calls :meth:`PlcProgram.advance` every scan period (``program.scan_s``) with
  the wall time passed;
- the faults of the link live here: slow replies, dropped connections (the server shut
  down and listening again later), restarts (program to power-on, connections dropped),
  each now or a given time into the motion.

Everything runs on the event loop the server was started on; :mod:`mppf.sim.plc.host`
hosts it in a background thread for synchronous callers.
"""

from __future__ import annotations

import asyncio
import contextlib
import time

from pymodbus.constants import ExcCodes
from pymodbus.framer import FramerType
from pymodbus.server import ModbusSerialServer, ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from mppf.core.errors import InputError
from mppf.drivers.modbus_adapter import RTU_SILENCE_CHARS
from mppf.sim.plc.program import PlcProgram

LINK_FAULTS = ("slow", "drop", "restart")
"""Faults of the link (the rest of :data:`mppf.sim.faults.KINDS` act on the program)."""
LINK_PARAMETERS = {"slow": ("delay_ms",), "drop": ("duration_s", "after_writes"), "restart": ("downtime_s",)}
"""The parameters of each link fault (besides ``after_s``)."""

_FC_READ = 3


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


class PlcServer:
    """A PLC program served over Modbus (run its coroutines on one asyncio loop).

    Parameters
    ----------
    program : PlcProgram
    unit : int
        Modbus unit (device) id; other ids get exception 4 from pymodbus.

    Attributes
    ----------
    slow_s : float
        Delay of every reply (s; fault "slow").
    master_writes : int
        Write requests received (every function 6 or 16 request that reached the device).
    on_write : callable or None
        Called as ``on_write(address, values, time.monotonic())`` for every master write
        (benchmarks time the arrival of a STOP with it).
    """

    def __init__(self, program: PlcProgram, *, unit: int = 1):
        if not 1 <= unit <= 247:
            raise InputError(f"Modbus unit id must be 1..247, got {unit}")
        self.program = program
        self.unit = unit
        self.slow_s = 0.0
        self._server = None
        self._server_factory = None
        self._internal = False
        self._ticker: asyncio.Task | None = None
        self._tasks: set[asyncio.Task] = set()
        self._dropped = False
        self._drop_after_writes: tuple[int, float] | None = None
        self._timed: list[tuple[float, str, dict]] = []  # link faults due a time into the motion
        self.master_writes = 0
        self.on_write = None
        self.frame_silence_s = 0.0  # RTU: the slave answers after 3.5 characters of silence

    # ------------------------------------------------------------- the action ---
    async def _action(self, function_code, start, address, count, registers, set_values):
        """pymodbus action hook: runs before every request is applied."""
        if registers is not self.program.regs:  # a new server: the program works on its register list
            if start != 0:
                raise RuntimeError(f"register block starts at {start}, expected 0")
            self.program.adopt_image(registers)
        if self._internal:
            return None
        if self.frame_silence_s:
            time.sleep(self.frame_silence_s)  # sub-millisecond: the loop's timers are too coarse
        if self.slow_s:
            await asyncio.sleep(self.slow_s)
        if not set_values:
            return None
        if self._drop_after_writes is not None:
            left, duration = self._drop_after_writes
            if left <= 1:
                self._drop_after_writes = None
                await self.drop(duration)  # the link is gone: this write is not stored, never answered
                return ExcCodes.DEVICE_FAILURE
            self._drop_after_writes = (left - 1, duration)
        self.master_writes += 1
        if self.on_write is not None:
            self.on_write(address, list(set_values), time.monotonic())
        return None  # pymodbus stores the values now; the program acts on them in its next scan

    # ---------------------------------------------------------------- serving ---
    def _device(self) -> SimDevice:
        return SimDevice(
            id=self.unit,
            simdata=[SimData(0, count=self.program.map.total_registers, values=0, datatype=DataType.REGISTERS)],
            action=self._action,
        )

    async def _listen(self) -> None:
        server = self._server_factory()
        await server.serve_forever(background=True)
        self._internal = True
        try:  # one internal request: the action hook gives the program the new register list
            await server.async_getValues(self.unit, _FC_READ, 0, 1)
        finally:
            self._internal = False
        self._server = server
        self.program.publish()

    async def start_tcp(self, host: str = "127.0.0.1", port: int = 0) -> int:
        """Serve Modbus TCP on ``host:port`` (0: a free port); return the port."""
        address = [host, port]
        self._server_factory = lambda: _TcpServer(self._device(), address=tuple(address))
        await self._listen()
        address[1] = self._server.transport.sockets[0].getsockname()[1]  # the port bound
        self._ticker = asyncio.get_running_loop().create_task(self._run_scan())
        return address[1]

    async def start_rtu(self, port: str, *, baud: int = 115200, parity: str = "E", stopbits: int = 1) -> None:
        """Serve Modbus RTU on serial device ``port`` (each reply after 3.5 characters of silence)."""
        bits = 1 + 8 + (parity != "N") + stopbits  # start, data, parity, stop
        self.frame_silence_s = RTU_SILENCE_CHARS * bits / baud
        self._server_factory = lambda: _SerialServer(
            self._device(), framer=FramerType.RTU, port=port, baudrate=baud, parity=parity, stopbits=stopbits,
            bytesize=8,
        )
        await self._listen()
        self._ticker = asyncio.get_running_loop().create_task(self._run_scan())

    async def _run_scan(self) -> None:
        """The PLC scan: advance the program by the wall time passed, every scan period."""
        last = due = time.monotonic()
        while True:
            due += self.program.scan_s
            await asyncio.sleep(max(0.0, due - time.monotonic()))
            now = time.monotonic()
            due = max(due, now - self.program.scan_s)  # a late scan is not followed by a burst of scans
            self.program.advance(now - last)
            last = now
            self._run_timed()

    def _run_timed(self) -> None:
        """Trigger the link faults whose time into the motion has come."""
        if not self._timed or self.program.state != "EXECUTING":
            return
        for entry in list(self._timed):
            after_s, kind, params = entry
            if self.program.motion_time_s >= after_s:
                self._timed.remove(entry)
                self._apply_link_fault(kind, params)

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

    # ------------------------------------------------------------ link faults ---
    def inject(self, kind: str, **params) -> None:
        """Inject a fault (call on the server's loop): ``slow``, ``drop`` and ``restart`` act on
        the link, the others on the program (:meth:`PlcProgram.inject`).

        Parameters
        ----------
        kind : {"stuck", "estop", "overpressure", "freeze", "local", "slow", "drop", "restart"}
        **params
            slow: ``delay_ms``. drop: ``duration_s`` (2.0), ``after_writes`` (drop on the n-th
            master write, which is not stored). restart: ``downtime_s`` (0.3). Each of the
            three takes ``after_s``: simulated seconds into the motion of the current or next
            GO (None: now). The program's faults: see :meth:`PlcProgram.inject`.

        Raises
        ------
        InputError
            Unknown fault or bad parameters.
        """
        if kind not in LINK_FAULTS:
            self.program.inject(kind, **params)
            return
        params = dict(params)
        after_s = params.pop("after_s", None)
        unknown = sorted(set(params) - set(LINK_PARAMETERS[kind]))
        if unknown:
            raise InputError(f"fault {kind!r}: unexpected keyword argument {unknown[0]!r}",
                             hint=f"{kind} takes {', '.join(LINK_PARAMETERS[kind])} and after_s (docs/simulator.md)")
        for name in ("delay_ms", "duration_s", "downtime_s"):
            if name in params and not params[name] >= 0:
                raise InputError(f"fault {kind!r}: {name} must be >= 0, got {params[name]}")
        if after_s is None:
            self._apply_link_fault(kind, params)
        else:
            self._timed.append((float(after_s), kind, params))

    def _apply_link_fault(self, kind: str, params: dict) -> None:
        if kind == "slow":
            self.slow_s = params.get("delay_ms", 0.0) / 1000.0
        elif kind == "drop" and params.get("after_writes") is not None:
            self._drop_after_writes = (int(params["after_writes"]), float(params.get("duration_s", 2.0)))
        elif kind == "drop":
            self._spawn(self.drop(float(params.get("duration_s", 2.0))))
        else:
            self._spawn(self.restart(float(params.get("downtime_s", 0.3))))

    def clear_faults(self) -> None:
        """Remove every injected condition, of the link and of the program (latched faults stay)."""
        self._drop_after_writes = None
        self._timed = []
        self.slow_s = 0.0
        self.program.clear_faults()

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
        self.program.restart()
        await self.drop(downtime_s)


