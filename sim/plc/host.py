"""The simulated PLC in a background thread, for synchronous callers (tests, dry runs, ``mppf sim``).

:func:`start_simulated_plc` makes a :class:`~mppf.sim.plc.program.PlcProgram`, serves it
with a :class:`~mppf.sim.plc.server.PlcServer` (Modbus TCP on a loopback port, or RTU on
a pseudo-terminal pair or a serial device) on an asyncio loop in a daemon thread, and
returns a :class:`SimHandle` whose methods are thread-safe; :func:`run_simulated_plc` is
the same as a context manager. See ``docs/simulator.md``.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
import time
from collections.abc import Iterator

import numpy as np

from mppf.core.errors import InputError, LinkError
from mppf.model.press import PressConfig, example_press_path, load_press
from mppf.sim.faults import FaultSpec
from mppf.sim.plc.program import PlcProgram
from mppf.sim.plc.server import PlcServer
from mppf.sim.plc.settings import SimTransport, split_options
from mppf.sim.serial_pty import PtyPair


class SimHandle:
    """A running simulated PLC, hosted in a background thread.

    Attributes
    ----------
    url : str
        ``tcp://127.0.0.1:PORT?unit=1`` or ``rtu:///dev/pts/N?baud=115200&parity=E&unit=1``.
    plc : PlcProgram
        The PLC program (read its attributes; act on it only through the methods below).
    server : PlcServer
        Its Modbus server.
    port : int or None
        TCP port.
    serial_port : str or None
        The client's end of the RTU pseudo-terminal pair (or the serial device).
    """

    def __init__(self, server: PlcServer):
        self.server = server
        self.plc = server.program
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
        """Inject a fault (see :meth:`PlcServer.inject` and docs/simulator.md)."""
        self._call(self.server.inject, kind, **params)

    def inject_spec(self, spec: FaultSpec) -> None:
        """Inject a parsed ``--fault`` spec."""
        self.inject(spec.kind, **spec.params)

    def clear_faults(self) -> None:
        """Remove injected conditions (see :meth:`PlcServer.clear_faults`)."""
        self._call(self.server.clear_faults)

    def release_estop(self) -> None:
        """Release a pressed e-stop (the ESTOP fault stays latched until RESET)."""
        self._call(self.plc.release_estop)

    def set_remote(self, remote: bool) -> None:
        """Turn the remote-enable key switch: True = remote (GO allowed), False = local."""
        self._call(self.plc.set_remote, remote)

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

    def state(self) -> str:
        """The PLC's state by name (``"IDLE"``, ``"EXECUTING"``...)."""
        return self._call(lambda: self.plc.state)

    def result(self) -> str:
        """The name of the result of the last acknowledged command (``"ACCEPTED"``, ``"NOT_OWNER"``...)."""
        return self._call(lambda: self.plc.map.results.name(self.plc.ack[3]))

    def restart(self, downtime_s: float = 0.3) -> None:
        """Restart the PLC now: registers to power-on state, connections dropped for ``downtime_s``."""
        self._call(self.server.restart, downtime_s)

    def drop_connections(self, duration_s: float) -> None:
        """Close every connection now and answer nothing for ``duration_s`` seconds."""
        self._call(self.server.drop, duration_s)

    def write_foreign_setpoint(self, matrix: str, row: int, col: int, value_mm: float) -> None:
        """Change one setpoint register as a foreign master would (stored at once, seen by the next scan)."""
        self._call(self.plc.write_foreign_setpoint, matrix, row, col, value_mm)

    def scans(self, n: int = 2) -> None:
        """Wait until the program has run ``n`` more scans (n >= 1)."""
        start = self._call(lambda: self.plc.heartbeat)
        deadline = time.monotonic() + 10.0
        while (self._call(lambda: self.plc.heartbeat) - start) % 65536 < n:
            if time.monotonic() > deadline:
                raise LinkError("the simulated PLC did not scan within 10 s (program halted?)")
            time.sleep(self.plc.scan_s / 2)

    def wait_idle(self, timeout_s: float = 10.0) -> dict[str, bool]:
        """Wait until the PLC is not busy; return the status flags."""
        deadline = time.monotonic() + timeout_s
        while True:
            flags = self.status_bits()
            if not flags["busy"] or time.monotonic() > deadline:
                return flags
            time.sleep(0.01)

    async def _stop_all(self) -> None:
        """Stop the server; cancel and await what its closed connections left running on this loop."""
        await self.server.stop()
        others = [t for t in asyncio.all_tasks() if t is not asyncio.current_task()]
        for task in others:
            task.cancel()
        await asyncio.gather(*others, return_exceptions=True)

    def stop(self) -> None:
        """Stop the server and the thread (idempotent)."""
        if self._stopped:
            return
        try:
            asyncio.run_coroutine_threadsafe(self._stop_all(), self._loop).result(timeout=10)
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


def start_simulated_plc(press: PressConfig | None = None, *, faults: list[FaultSpec] = (), unit: int = 1,
                        **options) -> SimHandle:
    """Start a simulated PLC in a background thread; the caller must ``stop()`` it.

    Parameters
    ----------
    press : PressConfig, optional
        Default: the bundled example press.
    faults : list of FaultSpec
        Faults to inject at start.
    unit : int
        Modbus unit id (1..247).
    **options
        The fields of :class:`~mppf.sim.plc.settings.SimTransport`: ``host`` and ``port``
        (TCP, port 0: a free port; used unless ``rtu`` or ``rtu_port``), ``rtu`` (serve RTU
        on a new pseudo-terminal pair, :class:`PtyPair`; ``url`` names the client's end),
        ``rtu_port`` (serve RTU on this serial device instead), ``baud`` and ``parity`` (on a
        pseudo-terminal pair whose kernel refuses parity settings,
        :attr:`PtyPair.supports_parity`, parity N is used instead; ``url`` always states the
        parity in use), ``paced`` (pace the pseudo-terminal relay at ``baud``, 11 bits/byte).
        The others are those of :class:`~mppf.sim.plc.settings.PlcSettings` (``word_order``,
        ``time_scale``, ``watchdog_s``, ``seed``, ``noise_mm``, ``scan_s``, ``remote``...);
        the watchdog runs on the wall clock.
    """
    press = press or load_press(example_press_path())
    transport, settings = split_options(options)
    if transport.parity not in ("N", "E", "O"):
        raise InputError(f"parity must be N, E or O, got {transport.parity!r}")
    server = PlcServer(PlcProgram(press, clock=time.monotonic, **settings), unit=unit)
    handle = SimHandle(server)
    handle._thread.start()
    try:
        handle.url = (_serve_rtu if transport.serial else _serve_tcp)(handle, transport, unit)
        for spec in faults:
            handle.inject_spec(spec)
    except BaseException:
        handle.stop()
        raise
    return handle


def _serve_rtu(handle: SimHandle, transport: SimTransport, unit: int) -> str:
    """Serve the handle's PLC over RTU (a new pseudo-terminal pair or a serial device); its URL."""
    baud, parity, serve_on = transport.baud, transport.parity, transport.rtu_port
    if serve_on is None:
        handle._pty = PtyPair(baud=baud if transport.paced else None)
        serve_on, handle.serial_port = handle._pty.port_a, handle._pty.port_b
        if not handle._pty.supports_parity:
            parity = "N"  # this kernel refuses parity on pseudo-terminals
    else:
        handle.serial_port = serve_on
    with _start_failure(f"serial device {serve_on}", "give an existing serial device, or 'pty'"):
        asyncio.run_coroutine_threadsafe(handle.server.start_rtu(serve_on, baud=baud, parity=parity),
                                         handle._loop).result(10)
    return f"rtu://{handle.serial_port}?baud={baud}&parity={parity}&unit={unit}"


def _serve_tcp(handle: SimHandle, transport: SimTransport, unit: int) -> str:
    """Serve the handle's PLC over Modbus TCP (port 0: a free one); its URL."""
    host, port = transport.host, transport.port
    with _start_failure(f"{host}:{port}", "choose another --port (0: a free one) or a local --host; "
                        "is another simulator already running there?"):
        handle.port = asyncio.run_coroutine_threadsafe(handle.server.start_tcp(host, port), handle._loop).result(10)
    return f"tcp://{host}:{handle.port}?unit={unit}"


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
