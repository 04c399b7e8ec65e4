"""The press driver on the register map, whatever carries the registers: sends one step safely, follows it.

:class:`PlcPress` implements :class:`mppf.core.presslink.PressLink` on a register
transport (``connect``, ``close``, ``read_holding``, ``write_registers``,
``write_command``, as :class:`mppf.drivers.modbus_adapter.ModbusAdapter` offers them) and
a clock (``now()``, ``sleep(s)``). :class:`mppf.drivers.modbus.ModbusPress` gives it
Modbus TCP / RTU and the wall clock; :class:`mppf.sim.plc.link.InProcessPress` the
simulated PLC's program itself and the program's simulated time. No register number
appears here (the register map of ``drivers/register_map.toml``). One press step
(:meth:`PlcPress.run_step`) is:

1. check the setpoints against the press limits and the PLC's own limits (nothing is
   written if one is beyond them);
2. check the PLC is ready (no fault, no e-stop, no motion);
3. upload both setpoint blocks (FC16, at most 122 registers a frame);
4. read every register back and compare;
5. write ``setpoint_crc`` and a new ``job_sequence`` in one request (the PLC checks the
   CRC and its limits, then acknowledges the sequence);
6. read the status: GO only if the sequence is acknowledged, the data valid, the PLC
   ready and neither faulted nor in e-stop;
7. GO (one attempt, never retried), then poll until motion ends, with a timeout;
8. read the actual positions and check every punch against its target.

Steps 1-7 are :mod:`mppf.drivers.handshake`, step 8 :mod:`mppf.drivers.follow`; STOP and
RESET and what is sent after trouble are :mod:`mppf.drivers.safety`. STOP is sent on
Ctrl-C, on a fault, on a timeout, on a refusal after GO and when the link is lost (once,
after reconnecting). Latched faults are reset only by :meth:`PlcPress.reset`. Every
command and write is recorded in the audit log (:mod:`mppf.drivers.audit`).
"""

from __future__ import annotations

import math
import time

import numpy as np

from mppf.core.errors import Cancelled, ConfigError, InputError, LinkError, MppfError, PlcError
from mppf.core.presslink import PressStatus, StepResult
from mppf.core.progress import NULL_REPORTER, Reporter
from mppf.drivers import codec, regmap as rm
from mppf.drivers.audit import NULL_AUDIT
from mppf.drivers.follow import Follow
from mppf.drivers.handshake import Handshake
from mppf.drivers.identity import identify
from mppf.drivers.safety import Safety
from mppf.planning.press import PressConfig

_STATUS_REGISTERS = ("status_word", "fault_code", "refusal_code", "acknowledged_sequence", "motion_sequence",
                     "plc_heartbeat")


class WallClock:
    """Real time: ``time.monotonic`` and ``time.sleep``."""

    @staticmethod
    def now() -> float:
        return time.monotonic()

    @staticmethod
    def sleep(seconds: float) -> None:
        time.sleep(seconds)


class PlcPress(Handshake, Follow, Safety):
    """A press PLC behind a register transport (a :class:`mppf.core.presslink.PressLink`).

    Connects on construction: reads the magic (word order), map version, matrix size and
    the PLC's stroke limits (:func:`mppf.drivers.identity.identify`).

    Parameters
    ----------
    io
        The register transport.
    url : PlcUrl or str
        Where the PLC is (messages, audit log).
    press : PressConfig or None
        The press description (limits, speed, tolerance). None is enough for
        :meth:`status`, :meth:`stop` and :meth:`reset` but not for :meth:`run_step`.
    word_order : {"auto", "ABCD", "CDAB"}
        Expected word order of 32-bit values; "auto" takes the PLC's.
    unit : int
        The PLC's unit id (messages).
    audit : AuditLog, optional
        Where commands and writes are recorded (default: nowhere).
    job_sha256 : str, optional
        Hash of the job being pressed, recorded in the audit log.
    register_map : RegisterMap, optional
        Default: the packaged map.
    poll_s : float
        Status polling period during motion (s of ``clock``).
    clock : object with ``now()`` and ``sleep(s)``
        Default :class:`WallClock`.

    Raises
    ------
    InputError
        Bad word order.
    LinkError
        The PLC cannot be reached, or is not an mppf press PLC with this register map.
    ConfigError
        The press description does not match the PLC's matrix size.
    """

    def __init__(self, io, url, press: PressConfig | None = None, *, word_order: str = "auto", unit: int = 1,
                 audit=None, job_sha256: str | None = None, register_map: rm.RegisterMap | None = None,
                 poll_s: float = 0.05, clock=None):
        if word_order != "auto":
            codec.check_word_order(word_order)
        self.url = url
        self.press = press
        self.map = register_map if register_map is not None else rm.load_register_map()
        self.audit = audit if audit is not None else NULL_AUDIT
        self.job_sha256 = job_sha256
        self.poll_s = float(poll_s)
        self._clock = clock if clock is not None else WallClock()
        self._last_sequence = 0
        self._io = io
        try:
            self._io.connect()
            self.identity = identify(self._io, self.map, self.url, unit, word_order, press)
            self._connected()
        except Exception as exc:
            self.close()
            self._record("connect", "failed", detail=str(exc))
            raise
        self._record("connect", "ok", detail=f"word order {self.identity.word_order}, "
                     f"{self.identity.rows} x {self.identity.cols} punches")

    def _connected(self) -> None:
        """Called once the identity is checked (the Modbus driver starts its heartbeat)."""

    def close(self) -> None:
        """Disconnect (the press is not stopped)."""
        self._io.close()

    def __enter__(self) -> PlcPress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------------------------
    # registers, status, commands
    # ------------------------------------------------------------------------------
    def _field(self, name: str) -> rm.Field:
        return self.map[name]

    def _read_field(self, name: str, **kw) -> list[int]:
        f = self._field(name)
        return self._io.read_holding(f.address, f.count, max_chunk=self.map.max_read_registers, **kw)

    def _record(self, action: str, outcome: str, *, sequence: int | None = None, detail: str = "") -> None:
        self.audit.record(str(self.url), action, outcome, job_sha256=self.job_sha256, sequence=sequence,
                          detail=detail)

    def _status_words(self) -> dict[str, int]:
        first = min(self._field(n).address for n in _STATUS_REGISTERS)
        end = max(self._field(n).end for n in _STATUS_REGISTERS)
        words = self._io.read_holding(first, end - first, max_chunk=self.map.max_read_registers)
        return {n: words[self._field(n).address - first] for n in _STATUS_REGISTERS}

    def _status_from(self, raw: dict[str, int]) -> PressStatus:
        flags = self.map.status_flags(raw["status_word"])
        return PressStatus(
            **{k: flags[k] for k in ("ready", "busy", "in_position", "fault", "estop", "remote", "data_valid")},
            fault_code=raw["fault_code"],
            acknowledged_sequence=raw["acknowledged_sequence"],
            plc_heartbeat=raw["plc_heartbeat"],
            fault_text=self.map.fault_text(raw["fault_code"]),
            simulated=flags.get("simulated", False),
        )

    def status(self) -> PressStatus:
        """Read the PLC status (retried reads).

        Raises
        ------
        LinkError, PlcError
        """
        return self._status_from(self._status_words())

    def status_report(self) -> dict:
        """Everything ``mppf status`` shows: identity, status bits, codes, sequences, heartbeats."""
        raw = self._status_words()
        st = self._status_from(raw)
        return {
            "plc": str(self.url),
            "word_order": self.identity.word_order,
            "map_version": self.identity.map_version,
            "rows": self.identity.rows,
            "cols": self.identity.cols,
            "limits_mm": {k: list(v) for k, v in self.identity.limits_mm.items()},
            "status": {k: getattr(st, k) for k in ("ready", "busy", "in_position", "fault", "estop", "remote",
                                                    "data_valid", "simulated")},
            "fault_code": st.fault_code,
            "fault_text": st.fault_text,
            "refusal_code": raw["refusal_code"],
            "refusal_text": self.map.fault_text(raw["refusal_code"]),
            "acknowledged_sequence": st.acknowledged_sequence,
            "motion_sequence": raw["motion_sequence"],
            "plc_heartbeat": st.plc_heartbeat,
            "master_heartbeat": self._read_field("master_heartbeat")[0],
        }

    def _command(self, name: str, arg: int = 0) -> None:
        """Write ``command`` and ``command_arg`` in one request (one attempt)."""
        cmd, carg = self._field("command"), self._field("command_arg")
        if carg.address != cmd.address + 1:
            raise ConfigError("register map: command_arg must follow command")
        self._io.write_command(cmd.address, [self.map.command(name), int(arg)])

    # ------------------------------------------------------------------------------
    # one press step
    # ------------------------------------------------------------------------------
    def run_step(
        self,
        upper_mm: np.ndarray,
        lower_mm: np.ndarray,
        *,
        reporter: Reporter = NULL_REPORTER,
        timeout_s: float | None = None,
    ) -> StepResult:
        """Validate, upload, verify, start and follow one press step (see the module docstring).

        Parameters
        ----------
        upper_mm, lower_mm : (rows, cols) float
            Tip-height setpoints, no NaN.
        reporter : Reporter
            Receives "upload" progress (registers written and read back), then "motion"
            progress (mm of travel done, summed over all punches).
        timeout_s : float, optional
            Motion timeout; default twice the time of the longest move plus 10 s.

        Returns
        -------
        StepResult

        Raises
        ------
        LimitError, InputError
            Nothing was written.
        LinkError
            The link failed; STOP was attempted once if GO had been sent.
        PlcError
            The PLC refused a request (before GO: nothing moved; after GO: STOP was sent).
        PressRefused
            Verification failed or the PLC refused the job or GO; nothing moved.
        PressFault
            A fault, e-stop, watchdog, timeout, or punches out of tolerance; STOP was sent.
        Cancelled
            Ctrl-C; STOP was sent.
        """
        if timeout_s is not None and not (math.isfinite(timeout_s) and timeout_s > 0):
            raise InputError(f"the motion timeout must be a positive number of seconds, got {timeout_s}",
                             hint="give --timeout in s, or leave it out for the default")
        go_sent = False
        seq = None
        try:
            # steps 1-6: limits, readiness, upload, read-back, validation by the PLC
            seq, targets_mm = self._prepare(upper_mm, lower_mm, reporter)
            start_mm = self.read_actuals_mm()
            # step 7: GO, once
            go_sent = True
            self._go(seq)
            # step 8: follow the motion to its end, check the positions
            return self._follow(seq, targets_mm, start_mm, reporter, timeout_s, self._clock.now())
        except KeyboardInterrupt:
            reporter.finish()
            self._stop_after_trouble("cancelled by the operator", fresh=True)
            raise Cancelled("cancelled by the operator; STOP was sent to the press") from None
        except PlcError as exc:
            if not go_sent:
                raise  # refused before GO: nothing moved
            reporter.finish()
            raise self._refused_after_go(exc, seq) from None
        except LinkError as exc:
            reporter.finish()
            raise self._lost_link(exc, seq, go_sent) from None
        except Exception as exc:
            # the driver's own failures (PressFault, PressRefused, ...) have already done what is
            # safe; anything else after GO (a bug, a failing progress display) must not leave
            # the press moving until the watchdog notices
            if go_sent and not isinstance(exc, MppfError):
                self._stop_after_trouble(f"unexpected error: {type(exc).__name__}: {exc}")
            raise

    def upload(self, upper_mm: np.ndarray, lower_mm: np.ndarray, *, reporter: Reporter = NULL_REPORTER) -> int:
        """Check, upload, verify and have the PLC validate one step, without starting it.

        Steps 1-6 of :meth:`run_step` (no GO): the setpoints are in the PLC, read back,
        and acknowledged under a new job sequence.

        Returns
        -------
        int
            The job sequence the PLC acknowledged.

        Raises
        ------
        LimitError, InputError, PressRefused, LinkError, PlcError
            As :meth:`run_step`.
        """
        try:
            return self._prepare(upper_mm, lower_mm, reporter)[0]
        except LinkError as exc:
            reporter.finish()
            raise self._lost_link(exc, None, False) from None
