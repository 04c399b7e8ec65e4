"""The Modbus press driver: sends one press step to the PLC safely and follows it.

:class:`ModbusPress` implements :class:`mppf.core.presslink.PressLink` over Modbus TCP or
RTU, on the register map of ``drivers/register_map.toml`` (no register number appears
here). One press step (:meth:`ModbusPress.run_step`) is:

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

STOP is sent on Ctrl-C, on a fault, on a timeout and when the link is lost (once,
after reconnecting). Latched faults are reset only by :meth:`ModbusPress.reset`. A
heartbeat thread changes ``master_heartbeat`` every ``heartbeat_s`` while connected.
Every command and write is recorded in the audit log (:mod:`mppf.drivers.audit`).
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass

import numpy as np

from mppf.drivers import regmap as rm
from mppf.drivers.audit import NULL_AUDIT
from mppf.drivers.modbus_adapter import ModbusAdapter
from mppf.drivers.url import PlcUrl, parse_plc_url
from mppf.core.errors import (Cancelled, ConfigError, InputError, LimitError, LinkError, MppfError, PlcError,
                         PressFault, PressRefused)
from mppf.planning.press import PressConfig
from mppf.core.presslink import PressStatus, StepResult
from mppf.core.progress import NULL_REPORTER, Reporter

SIDES = ("upper", "lower")
MAX_LISTED = 8  # punches named in one error message
RECONNECT_S = 2.0  # how long to try reconnecting after a lost link before sending STOP
PLC_STALE_S = 1.0  # plc_heartbeat unchanged this long during motion: the PLC program has stopped
STOP_ATTEMPTS_AFTER_CTRL_C = 3  # a STOP interrupted by another Ctrl-C is sent again, this often at most


@dataclass(frozen=True)
class PlcIdentity:
    """What the PLC says about itself on connect.

    Attributes
    ----------
    word_order : {"ABCD", "CDAB"}
        Detected from the magic.
    map_version, rows, cols : int
    limits_mm : dict of str to (float, float)
        The PLC's own stroke limits, ``{"upper": (min, max), "lower": (min, max)}``.
    """

    word_order: str
    map_version: int
    rows: int
    cols: int
    limits_mm: dict


def motion_time_s(distance_mm: float, speed_mm_s: float, accel_mm_s2: float) -> float:
    """Time of a trapezoidal (or triangular) move of ``distance_mm`` from rest to rest."""
    d = abs(float(distance_mm))
    ramp_mm = speed_mm_s**2 / accel_mm_s2  # accelerate + decelerate to/from full speed
    if d >= ramp_mm:
        return d / speed_mm_s + speed_mm_s / accel_mm_s2
    return 2.0 * math.sqrt(d / accel_mm_s2)


class ModbusPress:
    """A press PLC on Modbus TCP or RTU (a :class:`mppf.core.presslink.PressLink`).

    Connects on construction: reads the magic (word order), map version, matrix size and
    the PLC's stroke limits, and starts the heartbeat.

    Parameters
    ----------
    url : str or PlcUrl
        ``tcp://host:port?unit=1`` or ``rtu:///dev/ttyUSB0?baud=115200&parity=E&unit=1``.
    press : PressConfig or None
        The press description (limits, speed, tolerance). None is enough for
        :meth:`status`, :meth:`stop` and :meth:`reset` but not for :meth:`run_step`.
    word_order : {"auto", "ABCD", "CDAB"}
        Expected word order of 32-bit values; "auto" takes the PLC's.
    timeout_s : float, optional
        Reply timeout of one request (default: the URL's, 1 s).
    heartbeat_s : float or None
        Period of the master heartbeat; None or 0 for none (status reading only).
    audit : AuditLog, optional
        Where commands and writes are recorded (default: nowhere).
    job_sha256 : str, optional
        Hash of the job being pressed, recorded in the audit log.
    register_map : RegisterMap, optional
        Default: the packaged map.
    poll_s : float
        Status polling period during motion.

    Raises
    ------
    InputError
        Bad URL or word order.
    LinkError
        The PLC cannot be reached, or is not an mppf press PLC with this register map.
    ConfigError
        The press description does not match the PLC's matrix size.
    """

    def __init__(
        self,
        url: str | PlcUrl,
        press: PressConfig | None = None,
        *,
        word_order: str = "auto",
        timeout_s: float | None = None,
        heartbeat_s: float | None = 0.25,
        audit=None,
        job_sha256: str | None = None,
        register_map: rm.RegisterMap | None = None,
        poll_s: float = 0.05,
    ):
        self.url = parse_plc_url(url) if isinstance(url, str) else url
        if word_order != "auto":
            rm.check_word_order(word_order)
        self.press = press
        self.map = register_map if register_map is not None else rm.load_register_map()
        self.audit = audit if audit is not None else NULL_AUDIT
        self.job_sha256 = job_sha256
        self.poll_s = float(poll_s)
        self.heartbeat_s = float(heartbeat_s) if heartbeat_s else 0.0
        self.heartbeat_errors = 0
        self.last_heartbeat_error: Exception | None = None
        self._last_sequence = 0
        self._hb_value = 0
        self._hb_stop = threading.Event()
        self._hb_thread: threading.Thread | None = None
        self._io = ModbusAdapter(self.url, timeout_s=timeout_s)
        try:
            self._io.connect()
            self.identity = self._identify(word_order)
            if self.heartbeat_s > 0:
                self.start_heartbeat()
        except Exception as exc:
            self.close()
            self._record("connect", "failed", detail=str(exc))
            raise
        self._record("connect", "ok", detail=f"word order {self.identity.word_order}, "
                     f"{self.identity.rows} x {self.identity.cols} punches")

    # ------------------------------------------------------------------------------
    # connection
    # ------------------------------------------------------------------------------
    def _field(self, name: str) -> rm.Field:
        return self.map[name]

    def _read_field(self, name: str, **kw) -> list[int]:
        f = self._field(name)
        return self._io.read_holding(f.address, f.count, max_chunk=self.map.max_read_registers, **kw)

    def _identify(self, word_order: str) -> PlcIdentity:
        """Read and check magic, map version, size and limits."""
        first = self._field("magic").address
        last = max(self._field(n).end for n in ("map_version", "rows", "cols", "lower_max"))
        try:
            words = self._io.read_holding(first, last - first, max_chunk=self.map.max_read_registers)
        except PlcError as exc:
            raise LinkError(
                f"the device at {self.url} is not an mppf press PLC with unit id {self.url.unit}: reading its "
                f"identity (registers {first}-{last - 1}) was refused: {exc.message}",
                hint="check the unit id (unit=N in the URL), the host and the port: another Modbus device answered",
            ) from None

        def get(name: str) -> list[int]:
            f = self._field(name)
            return words[f.address - first : f.end - first]

        try:
            detected = rm.detect_word_order(get("magic"), self.map.magic)
        except InputError:
            magic = get("magic")
            raise LinkError(
                f"the device at {self.url} is not an mppf press PLC: registers "
                f"{self._field('magic').address}-{self._field('magic').end - 1} hold "
                f"0x{magic[0]:04X} 0x{magic[1]:04X}, expected the magic 0x{self.map.magic:08X} "
                "in ABCD or CDAB word order",
                hint="check the URL (host, port, unit id): another Modbus device answered",
            ) from None
        if word_order != "auto" and word_order != detected:
            raise LinkError(
                f"the PLC at {self.url} uses word order {detected}, but {word_order} was requested",
                hint="use --word-order auto or fix the PLC's word-order setting",
            )
        (version,) = get("map_version")
        if version != self.map.version:
            raise LinkError(
                f"the PLC at {self.url} implements register map version {version}, "
                f"this mppf speaks version {self.map.version}",
                hint="update the PLC program or mppf so that both use the same register map",
            )
        (rows,), (cols,) = get("rows"), get("cols")
        limits = {}
        for side in SIDES:
            lo, hi = (
                float(rm.counts_to_mm(rm.decode_int32(get(f"{side}_{end}"), detected)[0], self.map.count_mm))
                for end in ("min", "max")
            )
            limits[side] = (lo, hi)
        ident = PlcIdentity(detected, version, rows, cols, limits)
        if self.press is not None and (rows, cols) != self.press.shape:
            raise ConfigError(
                f"the PLC at {self.url} drives {rows} x {cols} punches, the press description "
                f"'{self.press.name}' has {self.press.rows} x {self.press.cols}",
                hint="use the press description (or job) made for this press",
            )
        return ident

    def start_heartbeat(self, period_s: float | None = None) -> None:
        """Start (or restart) the heartbeat thread."""
        self.stop_heartbeat()
        if period_s:
            self.heartbeat_s = float(period_s)
        if self.heartbeat_s <= 0:
            raise InputError(f"heartbeat period must be positive, got {self.heartbeat_s}")
        self._hb_value = self._read_field("master_heartbeat")[0]
        self._hb_stop = threading.Event()
        self._hb_thread = threading.Thread(target=self._heartbeat_loop, name="mppf-heartbeat", daemon=True)
        self._hb_thread.start()

    def stop_heartbeat(self) -> None:
        """Stop the heartbeat thread (the PLC's watchdog will stop any motion)."""
        if self._hb_thread is not None:
            self._hb_stop.set()
            self._hb_thread.join()
            self._hb_thread = None

    def _heartbeat_loop(self) -> None:
        addr = self._field("master_heartbeat").address
        while True:
            self._hb_value = (self._hb_value + 1) & 0xFFFF
            try:
                self._io.write_command(addr, [self._hb_value])
            except (LinkError, PlcError) as exc:  # the main thread sees the link failure on its next request
                self.heartbeat_errors += 1
                self.last_heartbeat_error = exc
            if self._hb_stop.wait(self.heartbeat_s):
                return

    def close(self) -> None:
        """Stop the heartbeat and disconnect (the press is not stopped)."""
        self.stop_heartbeat()
        self._io.close()

    def __enter__(self) -> ModbusPress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------------------------
    # status and commands
    # ------------------------------------------------------------------------------
    def _record(self, action: str, outcome: str, *, sequence: int | None = None, detail: str = "") -> None:
        self.audit.record(str(self.url), action, outcome, job_sha256=self.job_sha256, sequence=sequence,
                          detail=detail)

    def _status_words(self) -> dict[str, int]:
        names = ("status_word", "fault_code", "refusal_code", "acknowledged_sequence", "motion_sequence",
                 "plc_heartbeat")
        first = min(self._field(n).address for n in names)
        end = max(self._field(n).end for n in names)
        words = self._io.read_holding(first, end - first, max_chunk=self.map.max_read_registers)
        return {n: words[self._field(n).address - first] for n in names}

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
        LinkError
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

    def _refusal_text(self) -> str:
        try:
            code = self._read_field("refusal_code")[0]
        except (LinkError, PlcError):
            return "reason unknown (refusal_code could not be read)"
        return self.map.fault_text(code)

    def stop(self, reason: str = "operator request") -> None:
        """Command STOP (one attempt, never retried; the PLC always accepts it).

        Raises
        ------
        LinkError
            STOP could not be delivered.
        """
        try:
            self._command("STOP")
        except (LinkError, PlcError) as exc:
            self._record("stop", "failed", sequence=self._last_sequence or None, detail=f"{reason}: {exc}")
            raise
        self._record("stop", "ok", sequence=self._last_sequence or None, detail=reason)

    def reset(self) -> None:
        """Reset latched faults (on request only).

        Raises
        ------
        PressRefused
            The PLC refused (e.g. the e-stop is still pressed).
        LinkError
        """
        try:
            self._command("RESET")
        except PlcError as exc:
            text = self._refusal_text()
            self._record("reset", "refused", detail=text)
            raise PressRefused(f"the PLC at {self.url} refused RESET: {text}",
                               hint="remove the cause (release the e-stop), then reset again") from exc
        except LinkError as exc:
            self._record("reset", "failed", detail=str(exc))
            raise
        self._record("reset", "ok")

    # ------------------------------------------------------------------------------
    # one press step
    # ------------------------------------------------------------------------------
    def check_setpoints(self, upper_mm, lower_mm) -> dict[str, np.ndarray]:
        """Check shapes and limits; return the setpoints in counts.

        Parameters
        ----------
        upper_mm, lower_mm : (rows, cols) float

        Returns
        -------
        dict of str to (rows, cols) int64
            Counts of 0.01 mm per side.

        Raises
        ------
        InputError
            Wrong shape or NaN.
        LimitError
            Setpoints beyond the press description's or the PLC's limits (lists the punches).
        """
        if self.press is None:
            raise InputError("a press description is needed to run a step", hint="pass press=PressConfig")
        grids = {"upper": np.asarray(upper_mm, dtype=float), "lower": np.asarray(lower_mm, dtype=float)}
        problems = []
        for side, grid in grids.items():
            if grid.shape != self.press.shape:
                raise InputError(f"{side} setpoints have shape {grid.shape}, the press has {self.press.shape}")
            if np.isnan(grid).any():
                r, c = np.argwhere(np.isnan(grid))[0]
                raise InputError(f"{side} setpoint of punch (row {r}, col {c}) is NaN",
                                 hint="fill inactive punches with parking heights (StepStrokes.setpoints_mm)")
            axis = getattr(self.press, side)
            plc_lo, plc_hi = self.identity.limits_mm[side]
            lo, hi = max(axis.min_mm, plc_lo), min(axis.max_mm, plc_hi)
            for r, c in np.argwhere((grid < lo) | (grid > hi)):
                problems.append(f"{side} punch {r * self.press.cols + c} (row {r}, col {c}) = "
                                f"{grid[r, c]:.2f} mm, limits {lo:.2f}..{hi:.2f} mm")
        if problems:
            shown = "; ".join(problems[:MAX_LISTED]) + (f"; and {len(problems) - MAX_LISTED} more"
                                                        if len(problems) > MAX_LISTED else "")
            self._record("limits", "refused", detail=f"{len(problems)} setpoints beyond limits")
            raise LimitError(
                f"{len(problems)} setpoint(s) beyond the stroke limits, nothing was written to the PLC: {shown}",
                hint="re-plan the job for this press (limits from the press description and the PLC)",
            )
        return {side: rm.mm_to_counts(grid, self.map.count_mm) for side, grid in grids.items()}

    def _block(self, kind: str, side: str) -> tuple[int, int]:
        """(address, registers in use) of a setpoint/actual block."""
        return self._field(f"{side}_{kind}").address, self.map.words_in_use(self.press.rows, self.press.cols)

    def read_actuals_mm(self) -> dict[str, np.ndarray]:
        """Actual tip heights, ``{"upper": (rows, cols), "lower": (rows, cols)}`` in mm."""
        out = {}
        for side in SIDES:
            addr, n = self._block("actuals", side)
            words = self._io.read_holding(addr, n, max_chunk=self.map.max_read_registers)
            counts = rm.decode_int32(words, self.identity.word_order).reshape(self.press.shape)
            out[side] = rm.counts_to_mm(counts, self.map.count_mm)
        return out

    def _fault_bits(self) -> dict[str, np.ndarray]:
        n = self.press.rows * self.press.cols
        out = {}
        for side in SIDES:
            f = self._field(f"{side}_fault_bits")
            words = self._io.read_holding(f.address, self.map.bit_words_in_use(self.press.rows, self.press.cols),
                                          max_chunk=self.map.max_read_registers)
            out[side] = rm.unpack_bits(words, n).reshape(self.press.shape)
        return out

    def _next_sequence(self) -> int:
        raw = self._status_words()
        base = max(raw["acknowledged_sequence"], raw["motion_sequence"], self._last_sequence)
        return base % 0xFFFF + 1  # 1..65535, never 0

    def _require_ready(self, st: PressStatus, what: str) -> None:
        if st.estop:
            raise PressRefused(f"{what} refused: the e-stop of the press is pressed",
                               hint="release the e-stop, then 'mppf reset'")
        if st.fault:
            raise PressRefused(f"{what} refused: the PLC has a latched fault ({st.fault_text})",
                               hint="remove the cause, then 'mppf reset'")
        if st.busy:
            raise PressRefused(f"{what} refused: the press is moving", hint="wait for the motion to end or STOP it")
        if not st.ready:
            raise PressRefused(f"{what} refused: the PLC is not ready", hint="check the PLC (mode, hydraulics)")

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
            The link failed; STOP was attempted once.
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
            seq, targets_mm = self._prepare(upper_mm, lower_mm, reporter)
            start_mm = self.read_actuals_mm()
            go_sent = True
            self._go(seq)
            t_go = time.monotonic()
            return self._follow(seq, targets_mm, start_mm, reporter, timeout_s, t_go)
        except KeyboardInterrupt:
            reporter.finish()
            self._stop_after_trouble("cancelled by the operator", fresh=True)
            raise Cancelled("cancelled by the operator; STOP was sent to the press") from None
        except (LinkError, PlcError) as exc:
            if isinstance(exc, PlcError) and not go_sent:
                raise
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
        LimitError, InputError, PressRefused, LinkError
            As :meth:`run_step`.
        """
        try:
            return self._prepare(upper_mm, lower_mm, reporter)[0]
        except (LinkError, PlcError) as exc:
            if isinstance(exc, PlcError):
                raise
            reporter.finish()
            raise self._lost_link(exc, None, False) from None

    def _prepare(self, upper_mm, lower_mm, reporter: Reporter) -> tuple[int, dict[str, np.ndarray]]:
        """Limits, readiness, upload, read-back, CRC and sequence; return (sequence, targets mm)."""
        counts = self.check_setpoints(upper_mm, lower_mm)
        targets_mm = {side: rm.counts_to_mm(counts[side], self.map.count_mm) for side in SIDES}
        blocks = {side: rm.encode_int32(counts[side].ravel(), self.identity.word_order) for side in SIDES}
        self._require_ready(self.status(), "upload")
        seq = self._next_sequence()
        self._last_sequence = seq
        self._upload(blocks, seq, reporter)
        self._validate(blocks, seq, reporter)
        return seq, targets_mm

    def _upload(self, blocks: dict[str, list[int]], seq: int, reporter: Reporter) -> None:
        """Write both setpoint blocks, then read them back and compare every register."""
        n = sum(len(b) for b in blocks.values())
        reporter.start(f"upload job {seq} ({n} registers)", total=2 * n)
        for side in SIDES:
            addr, _ = self._block("setpoints", side)
            try:
                self._io.write_registers(addr, blocks[side], max_chunk=self.map.max_write_registers,
                                         on_chunk=reporter.advance)
            except (LinkError, PlcError) as exc:
                self._record("upload", "failed", sequence=seq, detail=f"{side}: {exc}")
                raise
        self._record("upload", "ok", sequence=seq, detail=f"{n} registers, word order {self.identity.word_order}")
        mismatches = []
        for side in SIDES:
            addr, count = self._block("setpoints", side)
            back = self._io.read_holding(addr, count, max_chunk=self.map.max_read_registers, on_chunk=reporter.advance)
            mismatches += [(side, addr + i, w, r) for i, (w, r) in enumerate(zip(blocks[side], back)) if w != r]
        reporter.finish()
        if mismatches:
            side, a, w, r = mismatches[0]
            self._record("verify", "failed", sequence=seq, detail=f"{len(mismatches)} registers differ")
            raise PressRefused(
                f"verification of job {seq} failed: {len(mismatches)} setpoint register(s) read back differ "
                f"from what was written (first: {side} block, register {a}: wrote {w}, read {r}); GO was not sent",
                hint="another master may be writing to the PLC; check, then run the step again",
            )
        reporter.info(f"job {seq}: {n} setpoint registers written and verified")

    def _validate(self, blocks: dict[str, list[int]], seq: int, reporter: Reporter) -> None:
        """Write CRC and sequence (one request); check the PLC acknowledged and is ready for GO."""
        crc_f, seq_f = self._field("setpoint_crc"), self._field("job_sequence")
        if seq_f.address != crc_f.end:
            raise ConfigError("register map: job_sequence must follow setpoint_crc (one request)")
        crc = rm.setpoint_crc32(blocks["upper"], blocks["lower"])
        words = rm.encode_uint32([crc], self.identity.word_order) + [seq]
        try:
            self._io.write_command(crc_f.address, words)
        except PlcError as exc:
            text = self._refusal_text()
            self._record("validate", "refused", sequence=seq, detail=f"crc 0x{crc:08X}: {text}")
            raise PressRefused(f"the PLC refused job {seq} (CRC 0x{crc:08X}): {text}; GO was not sent",
                               hint="run the step again; if it repeats, check the PLC limits and other masters") from exc
        except LinkError as exc:
            self._record("validate", "failed", sequence=seq, detail=str(exc))
            raise
        self._record("validate", "ok", sequence=seq, detail=f"crc 0x{crc:08X}")
        st = self.status()
        if st.acknowledged_sequence != seq or not st.data_valid:
            self._record("go", "not sent", sequence=seq, detail="sequence not acknowledged")
            raise PressRefused(
                f"the PLC did not acknowledge job {seq} (acknowledged sequence {st.acknowledged_sequence}, "
                f"data valid {st.data_valid}); GO was not sent",
                hint="another master may be writing to the PLC; run the step again",
            )
        try:
            self._require_ready(st, "GO")
        except PressRefused as exc:
            self._record("go", "not sent", sequence=seq, detail=exc.message)
            raise
        reporter.info(f"job {seq} validated by the PLC (CRC 0x{crc:08X})")

    def _go(self, seq: int) -> None:
        """GO with the job sequence: one attempt, never retried."""
        try:
            self._command("GO", seq)
        except PlcError as exc:
            text = self._refusal_text()
            self._record("go", "refused", sequence=seq, detail=text)
            raise PressRefused(f"the PLC refused GO for job {seq}: {text}; nothing moved",
                               hint="run the step again (it uploads and verifies afresh)") from exc
        except LinkError as exc:
            self._record("go", "failed", sequence=seq, detail=str(exc))
            raise
        self._record("go", "ok", sequence=seq)

    def _follow(self, seq, targets_mm, start_mm, reporter: Reporter, timeout_s, t0: float) -> StepResult:
        """Poll until motion ends; then check the actual positions."""
        travel = {side: np.abs(targets_mm[side] - start_mm[side]) for side in SIDES}
        total_mm = float(sum(t.sum() for t in travel.values()))
        if timeout_s is None:
            longest = max(float(t.max()) for t in travel.values())
            timeout_s = 2.0 * motion_time_s(longest, self.press.speed_mm_s, self.press.accel_mm_s2) + 10.0
        reporter.start(f"motion job {seq} (mm of travel)", total=max(total_mm, 1e-9))
        last_progress = time.monotonic()
        last_hb = None
        last_hb_change = time.monotonic()
        while True:
            raw = self._status_words()
            st = self._status_from(raw)
            now = time.monotonic()
            if st.fault or st.estop:
                reporter.finish()
                self._stop_after_trouble(f"fault: {st.fault_text}")
                raise self._fault_error(seq, st, targets_mm)
            lost = raw["acknowledged_sequence"] != seq or raw["motion_sequence"] != seq
            restarted = last_hb is not None and 0 < (last_hb - raw["plc_heartbeat"]) < 0x8000
            if lost or restarted:
                reporter.finish()
                self._stop_after_trouble("PLC restarted")
                beat = f", PLC heartbeat fell from {last_hb} to {raw['plc_heartbeat']}" if restarted else ""
                raise PressFault(
                    f"the PLC restarted (or another master took over) during job {seq}: acknowledged "
                    f"sequence {raw['acknowledged_sequence']}, motion sequence {raw['motion_sequence']}{beat}; "
                    "STOP was sent, the step did not complete",
                    hint="check the press, then run the step again",
                )
            if raw["plc_heartbeat"] != last_hb:
                last_hb, last_hb_change = raw["plc_heartbeat"], now
            elif now - last_hb_change > PLC_STALE_S:
                reporter.finish()
                self._stop_after_trouble("PLC heartbeat stale")
                raise PressFault(
                    f"job {seq}: the PLC heartbeat stayed at {last_hb} for {now - last_hb_change:.1f} s during "
                    "motion: the PLC program is not running (PLC in STOP mode, or halted); STOP was sent, but "
                    "the PLC may not act on it",
                    hint="stop the press at the machine and check the PLC before anything else",
                )
            if not st.busy:
                break
            if now - t0 > timeout_s:
                reporter.finish()
                self._stop_after_trouble(f"timeout after {timeout_s:.1f} s")
                raise PressFault(
                    f"job {seq}: motion did not end within {timeout_s:.1f} s; STOP was sent",
                    hint="check the hydraulics and punches; give --timeout for slow moves",
                )
            if now - last_progress >= 0.25:
                actual = self.read_actuals_mm()
                remaining = sum(float(np.abs(targets_mm[s] - actual[s]).sum()) for s in SIDES)
                reporter.update(max(0.0, total_mm - remaining))
                last_progress = now
            time.sleep(self.poll_s)
        duration = time.monotonic() - t0
        actual = self.read_actuals_mm()
        reporter.update(total_mm - sum(float(np.abs(targets_mm[s] - actual[s]).sum()) for s in SIDES))
        reporter.finish()
        errors = {s: actual[s] - targets_mm[s] for s in SIDES}
        max_error = max(float(np.abs(e).max()) for e in errors.values())
        off = self._out_of_tolerance(targets_mm, actual)
        if off:
            self._record("complete", "out of tolerance", sequence=seq, detail=f"{len(off)} punches")
            raise PressFault(
                f"job {seq}: {len(off)} punch(es) not in position within {self.press.position_tolerance_mm} mm "
                f"after the motion ended: " + self._list(off),
                hint="a punch may be stuck or blocked: inspect it before the next step",
            )
        self._record("complete", "ok", sequence=seq, detail=f"max error {max_error:.3f} mm, {duration:.2f} s")
        return StepResult(
            sequence=seq,
            target_upper_mm=targets_mm["upper"],
            target_lower_mm=targets_mm["lower"],
            actual_upper_mm=actual["upper"],
            actual_lower_mm=actual["lower"],
            max_error_mm=max_error,
            duration_s=duration,
        )

    def _out_of_tolerance(self, targets_mm, actual_mm) -> list[str]:
        tol = self.press.position_tolerance_mm + 0.5 * self.map.count_mm
        off = []
        for side in SIDES:
            for r, c in np.argwhere(np.abs(actual_mm[side] - targets_mm[side]) > tol):
                off.append(f"{side} (row {r}, col {c}) target {targets_mm[side][r, c]:.2f} mm, "
                           f"actual {actual_mm[side][r, c]:.2f} mm")
        return off

    @staticmethod
    def _list(items: list[str]) -> str:
        more = f"; and {len(items) - MAX_LISTED} more" if len(items) > MAX_LISTED else ""
        return "; ".join(items[:MAX_LISTED]) + more

    def _fault_error(self, seq: int, st: PressStatus, targets_mm) -> PressFault:
        """The PressFault for a fault or e-stop seen during motion (names faulted punches)."""
        what = "the e-stop was pressed" if st.estop and not st.fault else f"the PLC faulted: {st.fault_text}"
        details = ""
        try:
            bits = self._fault_bits()
            actual = self.read_actuals_mm()
            named = [f"{side} (row {r}, col {c}) target {targets_mm[side][r, c]:.2f} mm, "
                     f"actual {actual[side][r, c]:.2f} mm"
                     for side in SIDES for r, c in np.argwhere(bits[side])]
            if named:
                details = f"; faulted punches: {self._list(named)}"
        except (LinkError, PlcError):
            details = "; the per-punch fault bits could not be read"
        self._record("complete", "fault", sequence=seq, detail=f"{st.fault_text}{details}")
        return PressFault(
            f"job {seq}: {what} during motion; STOP was sent{details}",
            hint="remove the cause, then 'mppf reset' and run the step again",
        )

    def _reconnect(self, within_s: float = RECONNECT_S) -> None:
        """Open a fresh connection, trying for up to ``within_s`` seconds."""
        deadline = time.monotonic() + within_s
        while True:
            self._io.close()
            try:
                self._io.connect()
                return
            except (LinkError, PlcError):
                if time.monotonic() >= deadline:
                    raise
                time.sleep(0.1)

    def _stop_after_trouble(self, reason: str, *, fresh: bool = False) -> None:
        """Send STOP once (on a fresh connection if ``fresh``); a failure is recorded, not raised.

        ``fresh`` is for an interrupted request (Ctrl-C): its reply may still be on the way
        and must not be taken for the reply to STOP.
        """
        for _ in range(STOP_ATTEMPTS_AFTER_CTRL_C):
            try:
                if fresh:
                    self._reconnect()
                self.stop(reason)
                return
            except (LinkError, PlcError):
                return  # recorded by stop(); the caller raises the original trouble
            except KeyboardInterrupt:
                # Ctrl-C again while STOP was on its way: the operator wants the press stopped,
                # so STOP again (harmless to repeat) on a fresh connection
                fresh = True
                reason = f"{reason} (Ctrl-C again: STOP repeated)"
        self._record("stop", "failed", sequence=self._last_sequence or None,
                     detail=f"{reason}: interrupted by Ctrl-C {STOP_ATTEMPTS_AFTER_CTRL_C} times")

    def _lost_link(self, exc: LinkError, seq: int | None, go_sent: bool) -> LinkError:
        """The link failed during a step: STOP once after reconnecting (if GO was sent)."""
        if not go_sent:
            return LinkError(
                f"link to the PLC lost before GO: {exc.message}; GO was not sent, the press did not move",
                hint="check the link, then run the step again (it uploads and verifies afresh)",
            )
        try:
            self._reconnect()
            self.stop(f"link lost: {exc.message}")
            state = "STOP was sent after reconnecting"
            try:
                st = self.status()
                if seq is not None and st.acknowledged_sequence != seq:
                    state += (f"; the PLC restarted (it no longer knows job {seq}: acknowledged sequence "
                              f"{st.acknowledged_sequence}, PLC heartbeat {st.plc_heartbeat})")
            except (LinkError, PlcError):
                pass
        except (LinkError, PlcError):
            self._record("stop", "failed", sequence=seq, detail=f"no link: {exc.message}")
            state = "STOP could not be sent: stop the press at the machine"
        return LinkError(f"link to the PLC lost during job {seq} after GO: {exc.message}; {state}",
                         hint="check the press and the link, then run the step again")
