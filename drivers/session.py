"""A session with a press PLC: identity, status, the command mailbox, ownership, STOP, RESET.

:class:`PlcSession` is what ``mppf status``, ``mppf stop`` and ``mppf reset`` need, and the
base of the press driver (:class:`mppf.drivers.plc_press.PlcPress`). It works on a register
transport (``connect``, ``close``, ``read_holding``, ``write_registers``, ``write_command``,
as :class:`mppf.drivers.modbus_adapter.ModbusAdapter` offers them) and a clock (``now()``,
``sleep(s)``), and imports neither numpy nor pymodbus, so these commands start at once.

The protocol (docs/register-map.md): a command is the mailbox written in ONE request
(command, counter, master id, CRC, sequence); the PLC acknowledges it on a later scan by
copying the counter and the master id into the acknowledgement registers with a result
code, and the master waits for the acknowledgement of its own pair. STOP has its own
register and is obeyed from anyone. A master owns the PLC after CLAIM and keeps its lease
with the heartbeat (started by the transport's host after the claim); the mailbox, the nonce
and the auth words are :mod:`mppf.drivers.mailbox`'s. Every command and
write is written ahead into the audit log (:mod:`mppf.drivers.audit`).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from typing import Any

from mppf.core.errors import LinkError, PlcError, PressFault
from mppf.core.presslink import PressStatus
from mppf.drivers import codec, regmap as rm
from mppf.drivers.audit import NULL_AUDIT, Audited
from mppf.drivers.identity import identify
from mppf.drivers.mailbox import Mailbox, new_master_id

STATUS_SPAN = ("stop_request", "refused_setpoint_writes")
"""The registers read for a status: the STOP register and the whole status block (one request)."""
ACK_MARGIN_S = 0.25
"""Added to the acknowledgement timeout: the time a loaded master takes to poll."""
HEARTBEAT_MAX_S = 0.25
"""Longest heartbeat period (a watchdog of 2.5 s or more still gets 4 beats a second)."""
HEARTBEAT_DIVISOR = 10
"""The heartbeat period is at most the watchdog / this: a late beat still keeps within a quarter."""


class WallClock:
    """Real time: ``time.monotonic`` and ``time.sleep``."""

    @staticmethod
    def now() -> float:
        return time.monotonic()

    @staticmethod
    def sleep(seconds: float) -> None:
        time.sleep(seconds)


@dataclass(frozen=True)
class SessionOptions:
    """The settings of a :class:`PlcSession` beyond the transport, the URL and the press.

    Attributes
    ----------
    word_order : {"auto", "ABCD", "CDAB"}
        Expected word order of 32-bit values; "auto" takes the PLC's.
    unit : int
        The PLC's unit id (messages).
    audit : AuditLog, optional
        Where commands and writes are recorded, written ahead (default: nowhere).
    job_sha256 : str, optional
        Hash of the job being pressed, recorded in the audit log.
    register_map : RegisterMap, optional
        Default: the packaged map.
    clock : object with ``now()`` and ``sleep(s)``, optional
        Default :class:`WallClock`.
    reply_timeout_s : float
        The transport's reply timeout in s (for the acknowledgement timeout).
    master_id : int, optional
        This master's id (default: a random one).
    """

    word_order: str = "auto"
    unit: int = 1
    audit: Any = None
    job_sha256: str | None = None
    register_map: rm.RegisterMap | None = None
    clock: Any = None
    reply_timeout_s: float = 1.0
    master_id: int | None = None


class PlcSession(Mailbox):
    """A connected press PLC: status, STOP, and the owner's commands (no numpy, no pymodbus).

    Connects on construction and reads the PLC's identity (:func:`mppf.drivers.identity.identify`).

    Parameters
    ----------
    io
        The register transport.
    url : PlcUrl or str
        Where the PLC is (messages, audit log).
    press : PressConfig, optional
        The press description, checked against the PLC's matrix (needed to press).
    **options
        The fields of :class:`SessionOptions` (``word_order``, ``unit``, ``audit``,
        ``job_sha256``, ``register_map``, ``clock``, ``reply_timeout_s``, ``master_id``).

    Attributes
    ----------
    master_id : int
    identity : PlcIdentity

    Raises
    ------
    InputError
        Bad word order.
    LinkError
        The PLC cannot be reached, or is not an mppf press PLC with this register map.
    ConfigError
        The press description does not match the PLC's matrix size.
    """

    def __init__(self, io, url, press=None, **options):
        opts = SessionOptions(**options)
        word_order, unit, job_sha256 = opts.word_order, opts.unit, opts.job_sha256
        if word_order != "auto":
            codec.check_word_order(word_order)
        self.url = url
        self.press = press
        self.map = opts.register_map if opts.register_map is not None else rm.load_register_map()
        self.audit = opts.audit if opts.audit is not None else NULL_AUDIT
        self.job_sha256 = job_sha256
        self.reply_timeout_s = float(opts.reply_timeout_s)
        self.master_id = int(opts.master_id) if opts.master_id else new_master_id()
        self._clock = opts.clock if opts.clock is not None else WallClock()
        self._counter = int.from_bytes(os.urandom(2), "big") % 0xFFFF + 1
        self._beat_counter = int.from_bytes(os.urandom(2), "big") % 0xFFFF
        self._nonce = 0  # the PLC's nonce for this master's lease (never written anywhere as it is)
        self._owner = False
        self._plc_halted = False
        self._not_at_rest = False  # a wait for rest after STOP ran out: the lease is kept, not released
        self._own_stop_count: int | None = None  # stop_count after this driver's last STOP
        self.confirm_reset = None  # asked before a RESET undoes a STOP of someone else (None: never reset it)
        self._last_sequence = 0
        self._io = io
        try:
            self._io.connect()
            self.identity = identify(self._io, self.map, self.url, unit, word_order, press)
        except BaseException as exc:
            self._io.close()
            self.audit.record(str(url), "connect", "failed", job_sha256=job_sha256, detail=str(exc))
            raise
        ident = self.identity
        self.audit.record(str(url), "connect", "ok", job_sha256=job_sha256,
                          detail=f"master 0x{self.master_id:08X}, word order {ident.word_order}, "
                                 f"{ident.rows} x {ident.cols} punches, scan {ident.scan_time_s * 1000:g} ms, "
                                 f"watchdog {(ident.watchdog_s or 0) * 1000:g} ms")

    def close(self) -> None:
        """Give the PLC back (RELEASE, when this master owns it and nothing moves) and disconnect.

        The press is not stopped: a motion in progress is ended by the PLC's watchdog once
        the heartbeat stops.
        """
        try:
            if self._owner and not self._plc_halted and self._rest_before_release():
                self.release()
        except (LinkError, PlcError, PressFault):
            pass  # recorded in the audit log; the lease lapses after the watchdog time
        finally:
            self._stop_heartbeat()
            self._io.close()

    def _rest_before_release(self) -> bool:
        """Before RELEASE: the press must be at rest (STOP and wait if it is not); False keeps the lease."""
        if self._not_at_rest:
            return False
        try:
            await_rest = getattr(self, "_stop_if_moving", None)
            if await_rest is not None:
                await_rest("closing while the press moves")
            return not self._not_at_rest
        except (LinkError, PlcError, PressFault):
            return False

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------------ timing ---
    @property
    def ack_timeout_s(self) -> float:
        """How long to wait for the acknowledgement of a command (or the PLC taking a STOP)."""
        scans = self.map.timing.get("command_ack_scans", 2) + 2
        return 2 * self.reply_timeout_s + scans * self.identity.scan_time_s + ACK_MARGIN_S

    @property
    def _poll_s(self) -> float:
        """Pause between two status reads while waiting for the PLC (half a scan)."""
        return min(max(self.identity.scan_time_s / 2, 0.002), 0.05)

    @property
    def heartbeat_period_s(self) -> float:
        """The heartbeat period: a tenth of the PLC's watchdog, at most :data:`HEARTBEAT_MAX_S`."""
        watchdog = self.identity.watchdog_s
        return HEARTBEAT_MAX_S if watchdog is None else min(HEARTBEAT_MAX_S, watchdog / HEARTBEAT_DIVISOR)

    # -------------------------------------------------------- heartbeat hooks ---
    def _start_heartbeat(self) -> None:
        """Start beating after a claim (the Modbus driver's thread; the in-process press beats as it waits)."""

    def _stop_heartbeat(self) -> None:
        """Stop beating."""

    def heartbeat_gap_s(self) -> float:
        """Longest time between two heartbeats since :meth:`_mark_heartbeat` (s)."""
        return 0.0

    def _mark_heartbeat(self) -> None:
        """Start measuring the heartbeat gap afresh (at the start of a step)."""

    def _beat(self) -> None:
        """One heartbeat: a newer counter, the master id and the auth of the nonce, in one request."""
        self._beat_counter = self._beat_counter % 0xFFFF + 1
        words = [self._beat_counter] + codec.u32_to_words(self.master_id, self.identity.word_order)
        words += codec.u32_to_words(codec.auth_crc32(self._nonce, words), self.identity.word_order)
        self._io.write_command(self.map["heartbeat_counter"].address, words, urgent=True)

    # ------------------------------------------------------------------ status ---
    def _status_raw(self) -> dict[str, int]:
        """The STOP register and the status block, decoded by field name (one read)."""
        first, count = self.map.span(*STATUS_SPAN)
        words = self._io.read_holding(first, count, max_chunk=self.map.max_read_registers)
        out = {}
        for field in self.map.fields.values():
            if first <= field.address < first + count:
                part = words[field.address - first : field.end - first]
                out[field.name] = part[0] if field.count == 1 else codec.words_to_u32(part, self.identity.word_order)
        out["flags"] = self.map.status_flags(out["status_word"])
        out["state_name"] = self.map.states.name(out["state"]) or f"unknown state {out['state']}"
        return out

    def _status_from(self, raw: dict) -> PressStatus:
        flags = raw["flags"]
        return PressStatus(state=raw["state_name"], **{name: flags[name] for name in rm.REQUIRED_BITS},
                           fault_code=raw["fault_code"], fault_text=self.map.fault_text(raw["fault_code"]),
                           owner_master=raw["owner_master"], validated_sequence=raw["validated_sequence"],
                           motion_sequence=raw["motion_sequence"], plc_heartbeat=raw["plc_heartbeat"])

    def status(self) -> PressStatus:
        """Read the PLC status (retried reads).

        Raises
        ------
        LinkError, PlcError
        """
        return self._status_from(self._status_raw())

    def status_report(self) -> dict:
        """Everything ``mppf status`` shows: identity, state, status bits, codes, owner, tokens, counters."""
        raw = self._status_raw()
        ident = self.identity
        hb_first, hb_count = self.map.span("heartbeat_counter", "heartbeat_master")
        hb = self._io.read_holding(hb_first, hb_count)
        return {
            "plc": str(self.url), "word_order": ident.word_order, "map_version": ident.map_version,
            "rows": ident.rows, "cols": ident.cols, "limits_mm": {k: list(v) for k, v in ident.limits_mm.items()},
            "scan_time_ms": round(ident.scan_time_s * 1000), "watchdog_ms": round((ident.watchdog_s or 0) * 1000),
            "position_tolerance_mm": ident.position_tolerance_mm,
            "state": raw["state_name"], "status": raw["flags"],
            "fault_code": raw["fault_code"], "fault_text": self.map.fault_text(raw["fault_code"]),
            "owner_master": raw["owner_master"],
            "last_command": {"command": self.map.commands.name(raw["ack_command"]), "counter": raw["ack_counter"],
                             "master": raw["ack_master"], "result": self.map.results.name(raw["result_code"]),
                             "result_text": self.map.result_text(raw["result_code"])},
            "validated": {"sequence": raw["validated_sequence"], "crc": raw["validated_crc"]},
            "motion": {"sequence": raw["motion_sequence"], "crc": raw["motion_crc"]},
            "last_sequence": raw["last_sequence"], "refused_writes": raw["refused_writes"],
            "stops": {"count": raw["stop_count"], "last_master": raw["last_stop_master"],
                      "cause": self.map.stop_causes.name(raw["stop_cause"])},
            "plc_heartbeat": raw["plc_heartbeat"],
            "heartbeat": {"master": codec.words_to_u32(hb[1:3], ident.word_order), "counter": hb[0]},
            "refused_setpoint_writes": raw["refused_setpoint_writes"],
        }

    # -------------------------------------------------------------------- STOP ---
    def stop(self, reason: str = "operator request", *, wait: bool = True) -> None:
        """STOP: its own register, one request, obeyed from anyone in every state.

        Parameters
        ----------
        reason : str
            Recorded in the audit log.
        wait : bool
            Wait until the PLC has taken the request (it writes ``stop_request`` back to 0).

        Raises
        ------
        LinkError
            STOP could not be delivered.
        PlcError
            The PLC refused the request (a device that is not an mppf press PLC).
        PressFault
            ``wait`` and the PLC did not take the STOP within :attr:`ack_timeout_s`.
        """
        words = [1] + codec.u32_to_words(self.master_id, self.identity.word_order)
        with Audited(self, "stop", sequence=self._last_sequence or None, detail=reason) as row:
            self._io.write_command(self.map["stop_request"].address, words, urgent=True)
            if wait:
                self._await_stop_taken(row)

    def _await_stop_taken(self, row: Audited) -> None:
        """Wait until the PLC has taken the STOP (``stop_request`` back to 0)."""
        deadline = self._clock.now() + self.ack_timeout_s
        try:
            while (raw := self._status_raw())["stop_request"] != 0:
                if self._clock.now() >= deadline:
                    row.outcome = "not taken"
                    raise PressFault(f"the PLC at {self.url} did not take the STOP within {self.ack_timeout_s:.1f} s",
                                     hint="stop the press at the machine, then check the PLC")
                self._clock.sleep(self._poll_s)
            self._own_stop_count = raw["stop_count"]  # this STOP is ours: no need to ask before its RESET
        except (LinkError, PlcError) as exc:  # the STOP itself was delivered; only the confirmation is missing
            row.detail = f"not confirmed: {exc.message}"
