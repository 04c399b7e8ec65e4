"""The in-process press: the press driver on the simulated PLC's program itself, instant and seeded.

:class:`InProcessPress` is the driver of :mod:`mppf.drivers.plc_press` (the same limits,
upload, read-back, validation, GO, motion following, fault reports, STOP and audit records
as :class:`mppf.drivers.modbus.ModbusPress`) with two things swapped:

- the register transport is :class:`ProgramIO`: reads and writes go straight into the
  :class:`~mppf.sim.plc.program.PlcProgram`'s register image (a refused write raises
  :class:`~mppf.core.errors.PlcError` with the program's exception code, as a Modbus
  exception reply does); no Modbus, no sockets;
- the clock is :class:`ProgramClock`: the program's simulated time, which moves only when
  the driver waits between two polls; the wait advances the program by that time at
  once, writing the master heartbeat first. No threads, no sleeping: a step of 20 s of
  motion takes a few hundredths of a second, and a run is repeatable (the noise on the
  positions is seeded).

So what the loop can observe is what the Modbus driver gives it: ``LimitError`` for
setpoints beyond the limits, ``PressRefused`` for a refusal, ``PressFault`` for a fault,
``Cancelled`` (after STOP) for Ctrl-C, and the same :class:`~mppf.core.presslink.StepResult`
with the actual positions read from the program (its ``duration_s`` in simulated seconds).
The faults of the program (stuck punch, e-stop, overpressure, freeze) are injected with
``press.program.inject(...)``; the link's own faults (slow replies, dropped connections)
do not exist here.
"""

from __future__ import annotations

from mppf.core.errors import PlcError
from mppf.drivers import codec
from mppf.drivers.plc_press import PlcPress
from mppf.planning.press import PressConfig
from mppf.sim.faults import FaultSpec
from mppf.sim.plc.program import PlcProgram

URL = "inprocess://simulated-plc"
"""How the in-process press names its PLC (messages, audit log)."""

SETTLE_S = 10.0
"""After a step, a press still moving (braking after STOP) runs on at most this long (simulated s)."""


class ProgramIO:
    """The register transport of the in-process press: the program's image, read and written directly.

    Same calls as :class:`mppf.drivers.modbus_adapter.ModbusAdapter` (chunked like its
    frames, so that a refused frame is refused alone), none of which can lose the link.
    """

    def __init__(self, program: PlcProgram):
        self.program = program
        self.requests = 0
        self._size = program.map.total_registers

    def connect(self) -> None:
        """Nothing to open."""

    def close(self) -> None:
        """Nothing to close."""

    def _check_range(self, address: int, count: int, what: str) -> None:
        if address < 0 or address + count > self._size:
            self._refuse(what, 2)

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
            self._check_range(start, n, f"reading {n} registers at {start}")
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

    def write_command(self, address: int, words) -> None:
        """Write a command (one request)."""
        self._write(address, [int(w) for w in words], f"command write at {address}")

    def _write(self, address: int, words: list[int], what: str) -> None:
        self.requests += 1
        self._check_range(address, len(words), what)
        code = self.program.write(address, words)
        if code is not None:
            self._refuse(what, int(code))


class ProgramClock:
    """The program's simulated time: ``sleep`` advances the program at once.

    Each wait first changes the master heartbeat (the master is alive while it polls), so
    the program's watchdog sees the master as a real one's heartbeat thread would show it.
    """

    def __init__(self, program: PlcProgram):
        self.program = program
        self._address = program.map["master_heartbeat"].address
        self._beat = 0

    def now(self) -> float:
        """Seconds of the program's time."""
        return self.program.now_s

    def beat(self) -> None:
        """Change the master heartbeat."""
        self._beat = (self._beat + 1) & 0xFFFF
        self.program.write(self._address, [self._beat])

    def sleep(self, seconds: float) -> None:
        """Let ``seconds`` pass in the program (one scan), after a heartbeat."""
        self.beat()
        self.program.advance(seconds)


class InProcessPress(PlcPress):
    """A :class:`~mppf.core.presslink.PressLink` driving a simulated PLC program in this thread.

    Parameters
    ----------
    press : PressConfig
        The press (also the program's: limits, speed, tolerance).
    seed : int
        Seed of the noise on the reported positions.
    noise_mm : float
        Standard deviation of that noise (0: exact).
    word_order : {"ABCD", "CDAB"}
        The program's word order (the driver detects it).
    watchdog_s : float or None
        The program's watchdog, in simulated seconds (None: off).
    faults : sequence of FaultSpec
        Faults of the program to inject at once (``stuck``, ``estop``, ``overpressure``, ``freeze``).
    audit : AuditLog, optional
        Where commands and writes are recorded.
    job_sha256 : str, optional
        Hash of the job being pressed, for the audit log.
    poll_s : float
        Simulated seconds between two status polls during motion.
    program : PlcProgram, optional
        Drive this program instead of a new one (its clock must be its own ``now_s``).

    Attributes
    ----------
    program : PlcProgram
    """

    def __init__(self, press: PressConfig, *, seed: int = 0, noise_mm: float = 0.0, word_order: str = "ABCD",
                 watchdog_s: float | None = 1.0, faults: tuple[FaultSpec, ...] = (), audit=None,
                 job_sha256: str | None = None, poll_s: float = 0.05, program: PlcProgram | None = None):
        self.program = program if program is not None else PlcProgram(
            press, word_order=word_order, watchdog_s=watchdog_s, seed=seed, noise_mm=noise_mm)
        for spec in faults:
            self.program.inject(spec.kind, **spec.params)
        super().__init__(ProgramIO(self.program), URL, press, audit=audit, job_sha256=job_sha256, poll_s=poll_s,
                         clock=ProgramClock(self.program))

    def _connected(self) -> None:
        self._clock.beat()  # the master is there: the program shows `remote`

    def run_step(self, upper_mm, lower_mm, **kwargs):
        """:meth:`PlcPress.run_step`; afterwards a stopped press is let come to rest.

        A real press brakes while the operator reads what went wrong; here time passes
        only while the driver waits, so after a step that ended early (STOP was sent on a
        fault, Ctrl-C, a refusal after GO) the program runs on until no punch moves, for
        at most :data:`SETTLE_S` simulated seconds (a halted program never comes to rest).
        """
        try:
            return super().run_step(upper_mm, lower_mm, **kwargs)
        finally:
            self._settle()

    def _settle(self) -> None:
        waited = 0.0
        while self.program.busy and not self.program.frozen and waited < SETTLE_S:
            self._clock.sleep(self.poll_s)
            waited += self.poll_s

    def __enter__(self) -> InProcessPress:
        return self
