"""A press step up to the motion: validation, ownership, upload, read-back, VALIDATE, GO.

:class:`Handshake` is the part of :class:`mppf.drivers.plc_press.PlcPress` that gets one
step into the PLC and started, in the order of the register map's handshake:

1. the setpoints pass the one job validator (:func:`mppf.planning.validate.check_setpoints`)
   against the press description and the PLC's limits; nothing is written otherwise;
2. the PLC neither faulted nor moving, and not owned by another master: CLAIM (the heartbeat
   starts); a finished job (COMPLETE, STOPPED) is RESET to IDLE;
3. both setpoint blocks written (FC16, at most 122 registers a frame) and read back;
4. VALIDATE with the job token (a new sequence and the CRC of what was written), acknowledged;
5. GO with the same token, one attempt, acknowledged, and the PLC in EXECUTING (or COMPLETE
   with our token for a job without travel) within the start timeout; the heartbeat must
   have kept a quarter of the watchdog since the step began.

Every write and command is written ahead into the audit log.
"""

from __future__ import annotations

import numpy as np

from mppf.core.errors import ConfigError, InputError, LimitError, PressFault, PressRefused
from mppf.drivers import codec
from mppf.drivers.session import Audited
from mppf.planning import validate

SIDES = ("upper", "lower")
MAX_LISTED = 8  # punches named in one error message


def listed(items: list[str]) -> str:
    """At most :data:`MAX_LISTED` items joined by "; ", with how many more."""
    more = f"; and {len(items) - MAX_LISTED} more" if len(items) > MAX_LISTED else ""
    return "; ".join(items[:MAX_LISTED]) + more


class Handshake:
    """Validation, ownership, upload, VALIDATE and GO (a mixin of ``PlcPress``)."""

    def check_setpoints(self, upper_mm, lower_mm, active=None) -> dict[str, np.ndarray]:
        """One step's setpoints through the one job validator, against the press and the PLC.

        Parameters
        ----------
        upper_mm, lower_mm : (rows, cols) float
        active : (rows, cols) bool, optional
            Given: parked punches must stand at their parking heights.

        Returns
        -------
        dict of str to (rows, cols) int64
            Counts of 0.01 mm per side.

        Raises
        ------
        InputError
            Wrong shape, not numbers, NaN.
        LimitError
            Setpoints beyond the press description's or the PLC's limits (lists the punches).
        """
        if self.press is None:
            raise InputError("a press description is needed to run a step", hint="pass press=PressConfig")
        try:
            grids = validate.check_setpoints(upper_mm, lower_mm, self.press, self.identity.limits_mm, active)
        except LimitError as exc:
            self.audit.record(str(self.url), "limits", "refused", job_sha256=self.job_sha256,
                              detail=exc.message[:500])
            raise
        return {side: codec.mm_to_counts(grids[side], self.map.count_mm) for side in SIDES}

    def check_job(self, job, press_file=None, press_source: str = "the press file") -> dict:
        """The whole job through the one job validator, against this PLC (and the press file).

        Raises
        ------
        ConfigError, LimitError
            Nothing was written (the refusal is in the audit log).
        """
        try:
            return validate.validate_job(job, press_file=press_file, plc_shape=(self.identity.rows, self.identity.cols),
                                         plc_limits=self.identity.limits_mm, press_source=press_source)
        except (LimitError, ConfigError) as exc:
            self.audit.record(str(self.url), "limits", "refused", job_sha256=self.job_sha256,
                              detail=exc.message[:500])
            raise

    def _block(self, kind: str, side: str) -> tuple[int, int]:
        """(address, registers in use) of a setpoint/actual block."""
        return self._field(f"{side}_{kind}").address, self.map.words_in_use(self.press.rows, self.press.cols)

    def _field(self, name: str):
        return self.map[name]

    # ------------------------------------------------------- before the upload ---
    def _require_ready(self, raw: dict, what: str) -> None:
        """Refuse (nothing written) a PLC that faulted, moves, or is owned by another master."""
        flags = raw["flags"]
        if flags["estop"]:
            raise PressRefused(f"{what} refused: the e-stop of the press is pressed",
                               hint="release the e-stop, then 'mppf reset'")
        if raw["state_name"] == "FAULT":
            fault = self.map.fault_text(raw["fault_code"])
            raise PressRefused(f"{what} refused: the PLC has a latched fault ({fault})",
                               hint="remove the cause, then 'mppf reset'")
        if flags["busy"]:
            raise PressRefused(f"{what} refused: the press is moving (state {raw['state_name']})",
                               hint="wait for the motion to end or STOP it")

    def _take_plc(self) -> None:
        """Own the PLC and bring it to a state that takes setpoints (a finished job is RESET).

        A press STOPPED by a STOP this driver did not send is RESET only when
        :attr:`confirm_reset` (a callable taking the question, returning True to reset) says so.
        """
        self._require_ready(self._status_raw(), "upload")
        self.claim()
        raw = self._status_raw()
        self._require_ready(raw, "upload")
        if raw["state_name"] == "STOPPED" and raw["stop_count"] != getattr(self, "_own_stop_count", None):
            self._confirm_foreign_stop(raw)
        if raw["state_name"] in ("COMPLETE", "STOPPED"):
            self.reset()

    def _confirm_foreign_stop(self, raw: dict) -> None:
        """The press was stopped by someone (a STOP request or the key switch): ask before RESET undoes it."""
        cause = self.map.stop_causes.name(raw["stop_cause"])
        who = (f"a STOP request of master 0x{raw['last_stop_master']:08X}" if cause == "STOP_REQUEST"
               else "the key switch turned to local" if cause == "REMOTE_DISABLED" else f"stop cause {cause}")
        question = (f"the press at {self.url} is STOPPED by {who} ({raw['stop_count']} STOP request(s) since the PLC "
                    "started); RESET it and go on")
        confirm = getattr(self, "confirm_reset", None)
        answer = bool(confirm(question)) if confirm is not None else False
        self.audit.record(str(self.url), "foreign stop", "reset confirmed" if answer else "not reset",
                          job_sha256=self.job_sha256, detail=question)
        if not answer:
            raise PressRefused(f"{question}? Not confirmed: nothing was written; the press stays STOPPED",
                               hint="find out who stopped the press and why; then run again at a terminal to "
                                    "confirm, or with --yes")

    def _prepare(self, upper_mm, lower_mm, reporter) -> tuple[int, int, dict[str, np.ndarray]]:
        """Validation, ownership, upload, read-back, VALIDATE; return (sequence, crc, targets mm)."""
        counts = self.check_setpoints(upper_mm, lower_mm)
        targets_mm = {side: codec.counts_to_mm(counts[side], self.map.count_mm) for side in SIDES}
        blocks = {side: codec.encode_int32(counts[side].ravel(), self.identity.word_order) for side in SIDES}
        self._mark_heartbeat()
        self._take_plc()
        seq = self._status_raw()["last_sequence"] % 0xFFFF + 1  # newer than any the PLC validated: 1..65535
        self._last_sequence = seq
        self._upload(blocks, seq, reporter)
        crc = codec.setpoint_crc32(blocks["upper"], blocks["lower"])
        self._validate(seq, crc, reporter)
        return seq, crc, targets_mm

    def _upload(self, blocks: dict[str, list[int]], seq: int, reporter) -> None:
        """Write both setpoint blocks (an audit row each, written ahead), read them back, compare."""
        n = sum(len(b) for b in blocks.values())
        reporter.start(f"upload job {seq} ({n} registers)", total=2 * n)
        for side in SIDES:
            addr, count = self._block("setpoints", side)
            with Audited(self, "upload", sequence=seq,
                         detail=f"{side} setpoints, registers {addr}..{addr + count - 1}, word order "
                                f"{self.identity.word_order}"):
                self._io.write_registers(addr, blocks[side], max_chunk=self.map.max_write_registers,
                                         on_chunk=reporter.advance)
        mismatches = []
        for side in SIDES:
            addr, count = self._block("setpoints", side)
            back = self._io.read_holding(addr, count, max_chunk=self.map.max_read_registers, on_chunk=reporter.advance)
            mismatches += [(side, addr + i, w, r) for i, (w, r) in enumerate(zip(blocks[side], back)) if w != r]
        reporter.finish()
        if mismatches:
            side, a, w, r = mismatches[0]
            self.audit.record(str(self.url), "verify", "failed", job_sha256=self.job_sha256, sequence=seq,
                              detail=f"{len(mismatches)} registers differ")
            raise PressRefused(
                f"verification of job {seq} failed: {len(mismatches)} setpoint register(s) read back differ "
                f"from what was written (first: {side} block, register {a}: wrote {w}, read {r}); GO was not sent",
                hint="another master may be writing to the PLC; check, then run the step again",
            )
        reporter.info(f"job {seq}: {n} setpoint registers written and verified")

    def _validate(self, seq: int, crc: int, reporter) -> None:
        """VALIDATE with the job token; the PLC must accept it and show it as validated."""
        with Audited(self, "validate", sequence=seq, detail=f"crc 0x{crc:08X}") as row:
            raw = self._command("VALIDATE", sequence=seq, crc=crc)
            if raw["result_code"]:
                row.outcome, row.detail = "refused", self.map.result_text(raw["result_code"])
                raise PressRefused(f"the PLC refused job {seq} (CRC 0x{crc:08X}): {row.detail}; GO was not sent",
                                   hint=self._validate_hint(self._result(raw)))
        reporter.info(f"job {seq} validated by the PLC (CRC 0x{crc:08X})")

    def _validate_hint(self, result: str) -> str:
        """What to do after a refused VALIDATE: the machine's own limits are not a passing hiccup."""
        ident = self.identity
        if result in ("NEIGHBOUR_STEP", "TIP_GAP", "LIMIT"):
            return (f"the job does not fit this press's own limits (dimpling limit {ident.dimpling_limit_mm:g} mm, "
                    f"smallest tip gap {ident.tip_gap_min_mm:g} mm, strokes {ident.limits_mm}): nothing moved; "
                    "plan the plate again with this machine's press file, never with edited strokes")
        return "run the step again; if it repeats, check the PLC and other masters ('mppf status')"

    # ------------------------------------------------------------------- GO ---
    def _check_heartbeat(self, seq: int) -> None:
        """Refuse GO when the heartbeat could not keep a quarter of the PLC's watchdog."""
        watchdog = self.identity.watchdog_s
        if watchdog is None:
            return
        gap = self.heartbeat_gap_s()
        if gap > watchdog / 4 and gap != float("inf"):
            gap = self._watch_heartbeat()
        if gap > watchdog / 4:
            hint = ("use a faster link, a PLC watchdog that suits it (watchdog_ms), or a lighter load on this computer"
                    if gap != float("inf") else "this driver has no heartbeat (heartbeat_s=None): give it one")
            self.audit.record(str(self.url), "go", "not sent", job_sha256=self.job_sha256, sequence=seq,
                              detail=f"heartbeat gap {gap:.3f} s > watchdog/4 {watchdog / 4:.3f} s")
            raise PressRefused(
                f"GO for job {seq} not sent: the heartbeat gap reached {gap:.2f} s, more than a quarter of the "
                f"PLC's watchdog ({watchdog:.2f} s); the PLC could stop the motion at any time",
                hint=hint)

    def _watch_heartbeat(self) -> float:
        """A late beat: watch the heartbeat afresh while the link carries the largest frames of a motion.

        A passing hiccup (a busy computer) is forgiven; a link that cannot carry the heartbeat
        beside the motion's reads (a slow serial line, a watchdog too short for it) is not.
        """
        self._mark_heartbeat()
        self.read_actuals_mm()
        self._clock.sleep(2 * self.heartbeat_period_s)
        return self.heartbeat_gap_s()

    def _go(self, seq: int, crc: int) -> dict:
        """GO with the job token, one attempt; return the status once the PLC executes it.

        Raises
        ------
        PressRefused
            The PLC refused GO (nothing moved).
        PressFault
            No acknowledgement, or the PLC did not start our job within the start timeout
            (STOP was sent).
        """
        self._check_heartbeat(seq)
        with Audited(self, "go", sequence=seq, detail=f"crc 0x{crc:08X}") as row:
            raw = self._await_ack(self._send("GO", sequence=seq, crc=crc))
            if raw is None:  # the acknowledgement may be lost; the motion token tells whether our GO started
                raw = self._started_by_token(seq, crc)
            if raw is None:
                row.outcome = "no acknowledgement"
                self._stop_after_trouble(f"GO of job {seq} not acknowledged")
                raise PressFault(f"the PLC did not acknowledge GO for job {seq} within {self.ack_timeout_s:.1f} s; "
                                 "STOP was sent", hint="check the PLC ('mppf status'), then run the step again")
            if raw["result_code"]:
                row.outcome, row.detail = "refused", self._go_refusal(raw)
                self._refused_go(seq, row.detail)
        return self._await_start(seq, crc, raw)

    def _refused_go(self, seq: int, why: str) -> None:
        """GO refused: read whether anything moves before saying so; STOP when it does. Always raises."""
        raw = self._status_raw()
        moving = raw["state_name"] in ("EXECUTING", "STOPPING") or raw["flags"]["busy"]
        if not moving and self._await_rest(within_s=self._rest_time_s() + 2 * self.poll_s):
            raise PressRefused(f"the PLC refused GO for job {seq}: {why}; nothing moved (state {raw['state_name']}, "
                               "the punches read still)", hint="run the step again (it uploads and verifies afresh)")
        self._stop_after_trouble(f"GO of job {seq} refused while the press moves")
        raise PressFault(
            f"the PLC refused GO for job {seq} ({why}), but the press was moving (state {raw['state_name']}, motion "
            f"job {raw['motion_sequence']} of CRC 0x{raw['motion_crc']:08X}, not ours): STOP was sent",
            hint="another master is driving the press: find it ('mppf status') before anything else")

    def _started_by_token(self, seq: int, crc: int) -> dict | None:
        """The status when the PLC executes our job (its motion token ours) without a readable acknowledgement."""
        raw = self._status_raw()
        ours = (raw["motion_sequence"], raw["motion_crc"]) == (seq, crc)
        return dict(raw, result_code=0) if ours and raw["state_name"] in ("EXECUTING", "COMPLETE") else None

    def _go_refusal(self, raw: dict) -> str:
        text = self.map.result_text(raw["result_code"])
        if self._result(raw) == "WRONG_STATE":
            text += f" (state {raw['state_name']}"
            text += ": the setpoints changed after validation)" if raw["state_name"] == "LOADED" else ")"
        return text

    def _await_start(self, seq: int, crc: int, raw: dict) -> dict:
        """Wait for EXECUTING (or COMPLETE with our token) after an accepted GO; anything else: STOP."""
        deadline = self._clock.now() + self.ack_timeout_s
        while True:
            ours = (raw["motion_sequence"], raw["motion_crc"]) == (seq, crc)
            if ours and raw["state_name"] in ("EXECUTING", "COMPLETE", "STOPPING", "STOPPED"):  # stopped: followed
                return raw
            if raw["state_name"] != "VALIDATED" or self._clock.now() >= deadline:
                break
            self._clock.sleep(self._poll_s)
            raw = self._status_raw()
        self._stop_after_trouble(f"job {seq} did not start")
        if raw["state_name"] == "FAULT":  # e.g. the e-stop pressed at the start of motion: say which fault
            raise PressFault(f"after GO for job {seq} the PLC went to FAULT "
                             f"({self.map.fault_text(raw['fault_code'])}) before the driver saw our job executing "
                             "(the punches may have begun to move); STOP was sent",
                             hint="remove the cause, then 'mppf reset' and run the step again")
        raise PressFault(f"after GO for job {seq} the PLC reports state {raw['state_name']} and motion job "
                         f"{raw['motion_sequence']} (CRC 0x{raw['motion_crc']:08X}), not our job executing; "
                         "STOP was sent", hint="check the PLC ('mppf status'), then run the step again")

