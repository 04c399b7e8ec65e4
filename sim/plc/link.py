"""The in-process press: the press driver on the simulated PLC's program itself, instant and seeded.

:class:`InProcessPress` is the driver of :mod:`mppf.drivers.plc_press` (the same validator,
claim, upload, read-back, VALIDATE, GO, motion following, fault reports, STOP and audit
records as :class:`mppf.drivers.modbus.ModbusPress`) with two things swapped:

- the register transport is :class:`ProgramIO`: reads and writes go straight into the
  :class:`~mppf.sim.plc.program.PlcProgram`'s register image, stored at once as a PLC's
  Modbus server stores them (a request outside the map raises
  :class:`~mppf.core.errors.PlcError` with exception 2, as a Modbus exception reply does);
  no Modbus, no sockets. The program acts on the writes in its next scan, like the real one;
- the clock is :class:`ProgramClock`: the program's simulated time, which moves only when
  the driver waits; each wait writes the owner's heartbeat and then runs one scan of the
  program over the time waited. No threads, no sleeping: a step of 20 s of motion takes a
  few hundredths of a second, and a run is repeatable (the noise on the positions is seeded).

So what the loop can observe is what the Modbus driver gives it: ``LimitError`` for
setpoints beyond the limits, ``PressRefused`` for a refusal, ``PressFault`` for a fault,
``Cancelled`` (after STOP) for Ctrl-C, and the same :class:`~mppf.core.presslink.StepResult`
with the actual positions read from the program (its ``duration_s`` in simulated seconds).
The faults of the program (stuck punch, e-stop, overpressure, freeze, key switch) are
injected with ``press.program.inject(...)``; the link's own faults (slow replies, dropped
connections, restarts) do not exist here.
"""

from __future__ import annotations

from mppf.core.errors import PlcError
from mppf.drivers import codec
from mppf.drivers.plc_press import PlcPress
from mppf.model.press import PressConfig
from mppf.sim.faults import FaultSpec
from mppf.sim.plc.program import PlcProgram

URL = "inprocess://simulated-plc"
"""How the in-process press names its PLC (messages, audit log)."""


class ProgramIO:
    """The register transport of the in-process press: the program's image, read and written directly.

    Same calls as :class:`mppf.drivers.modbus_adapter.ModbusAdapter` (chunked like its
    frames), none of which can lose the link.
    """

    def __init__(self, program: PlcProgram):
        self.program = program
        self.requests = 0
        self.writes = 0

    def connect(self) -> None:
        """Nothing to open."""

    def close(self) -> None:
        """Nothing to close."""

    def _refuse(self, what: str, code: int) -> None:
        error = PlcError(f"the PLC at {URL} refused {what}: exception {code} "
                         f"({codec.EXCEPTION_NAMES.get(code, 'unknown')})",
                         hint="read 'mppf status' for the PLC's fault code")
        error.exception_code = code
        raise error

    def read_holding(self, address: int, count: int, *, retries=None, max_chunk: int = 125, on_chunk=None) -> list[int]:
        """Read ``count`` registers from ``address`` (in chunks of ``max_chunk``, like FC3 frames)."""
        words: list[int] = []
        for start in range(address, address + count, max_chunk):
            n = min(max_chunk, address + count - start)
            self.requests += 1
            if start < 0 or start + n > self.program.map.total_registers:
                self._refuse(f"reading {n} registers at {start}", self.program.map.illegal_address)
            words.extend(self.program.read(start, n))
            if on_chunk is not None:
                on_chunk(n)
        return words

    def write_registers(self, address: int, words, *, retries=None, max_chunk: int = 122, on_chunk=None) -> None:
        """Write registers from ``address`` (in chunks of ``max_chunk``, like FC16 frames)."""
        for start, chunk in codec.chunks(address, [int(w) for w in words], max_chunk):
            self._write(start, chunk, f"writing {len(chunk)} registers at {start}")
            if on_chunk is not None:
                on_chunk(len(chunk))

    def write_command(self, address: int, words, *, urgent: bool = False) -> None:
        """Write a command (one request)."""
        self._write(address, [int(w) for w in words], f"command write at {address}")

    def _write(self, address: int, words: list[int], what: str) -> None:
        self.requests += 1
        self.writes += 1
        code = self.program.store(address, words)
        if code is not None:
            self._refuse(what, int(code))


class ProgramClock:
    """The program's simulated time: ``sleep`` beats (once the press owns the PLC) and runs one scan."""

    def __init__(self, program: PlcProgram):
        self.program = program
        self.on_sleep = None

    def now(self) -> float:
        """Seconds of the program's time."""
        return self.program.now_s

    def sleep(self, seconds: float) -> None:
        """Let ``seconds`` pass in the program: the owner's heartbeat first, then one scan."""
        if self.on_sleep is not None:
            self.on_sleep()
        self.program.advance(seconds)


class InProcessPress(PlcPress):
    """A :class:`~mppf.core.presslink.PressLink` driving a simulated PLC program in this thread.

    Parameters
    ----------
    press : PressConfig
        The press (also the program's: limits, speed, tolerance).
    faults : sequence of FaultSpec
        Faults of the program to inject at once (``stuck``, ``estop``, ``overpressure``,
        ``freeze``, ``local``).
    audit : AuditLog, optional
        Where commands and writes are recorded.
    job_sha256 : str, optional
        Hash of the job being pressed, for the audit log.
    poll_s : float
        Simulated seconds between two status polls during motion.
    program : PlcProgram, optional
        Drive this program instead of a new one (its clock must be its own ``now_s``).
    **settings
        The new program's :class:`~mppf.sim.plc.settings.PlcSettings`, e.g. ``seed`` and
        ``noise_mm`` (the noise on the reported positions), ``word_order`` (the driver
        detects it), ``watchdog_s`` (simulated s, None: off), ``scan_s`` (simulated s, as the
        program states it to the driver); unused with ``program``.

    Attributes
    ----------
    program : PlcProgram
    """

    def __init__(self, press: PressConfig, *, faults: tuple[FaultSpec, ...] = (), audit=None,
                 job_sha256: str | None = None, poll_s: float = 0.05, program: PlcProgram | None = None, **settings):
        self.program = program if program is not None else PlcProgram(press, **settings)
        for spec in faults:
            self.program.inject(spec.kind, **spec.params)
        clock = ProgramClock(self.program)
        self._beat_at = self._beat_gap = 0.0
        super().__init__(ProgramIO(self.program), URL, press, audit=audit, job_sha256=job_sha256, poll_s=poll_s,
                         clock=clock, reply_timeout_s=0.0)
        clock.on_sleep = self._beat_if_owner

    def _beat_if_owner(self) -> None:
        if self._owner:
            self._beat()
            now = self.program.now_s
            self._beat_gap, self._beat_at = max(self._beat_gap, now - self._beat_at), now

    def _start_heartbeat(self) -> None:
        self._beat_at = self.program.now_s

    def _mark_heartbeat(self) -> None:
        self._beat_gap = 0.0

    def heartbeat_gap_s(self) -> float:
        return max(self._beat_gap, self.program.now_s - self._beat_at)

    def __enter__(self) -> InProcessPress:
        return self
