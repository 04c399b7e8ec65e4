"""A press step after GO: follow the motion to COMPLETE and check where every punch stands.

:class:`Follow` is the part of :class:`mppf.drivers.plc_press.PlcPress` that polls the PLC
after GO. The step is complete only when the PLC reports COMPLETE with this job's token,
sets ``in_position``, and the driver's own reading of the actual positions puts every punch
within the tolerance of its target. Anything else ends the step with STOP (the heartbeat
goes on until the press is at rest) and :class:`~mppf.core.errors.PressFault`: a fault, a
STOP from someone else or the key switch, a restarted PLC (state or token lost, heartbeat
fallen), a halted PLC program (heartbeat stale), a timeout. Time is the press's clock, so
the same code follows a real press in wall time and the in-process press in simulated time.
"""

from __future__ import annotations

import math

import numpy as np

from mppf.core.errors import LinkError, PlcError, PressFault
from mppf.core.presslink import StepResult
from mppf.drivers import codec
from mppf.drivers.handshake import SIDES, listed


def abandon(reporter, why: str) -> None:
    """End the reporter's task without calling it done (a reporter without ``abandon`` just finishes)."""
    end = getattr(reporter, "abandon", None)
    if end is not None:
        end(why)
    else:
        reporter.finish()

PLC_STALE_S = 1.0  # plc_heartbeat unchanged this long during motion: the PLC program has stopped
LATE_BITS_SCANS = 10  # status bits may lag the state by this many scans before mppf stops believing them
TOO_SOON_FRACTION = 0.5  # COMPLETE sooner than this share of the fastest possible move: not believed
PROGRESS_S = 0.25  # actual positions read for the progress display this often during motion


def motion_time_s(distance_mm: float, speed_mm_s: float, accel_mm_s2: float) -> float:
    """Time of a trapezoidal (or triangular) move of ``distance_mm`` from rest to rest."""
    d = abs(float(distance_mm))
    ramp_mm = speed_mm_s**2 / accel_mm_s2  # accelerate + decelerate to/from full speed
    if d >= ramp_mm:
        return d / speed_mm_s + speed_mm_s / accel_mm_s2
    return 2.0 * math.sqrt(d / accel_mm_s2)


class Follow:
    """Motion following, fault reports and the final position check (a mixin of ``PlcPress``)."""

    def read_actuals_mm(self) -> dict[str, np.ndarray]:
        """Actual tip heights, ``{"upper": (rows, cols), "lower": (rows, cols)}`` in mm."""
        return self._read_heights_mm("actuals")

    def read_setpoints_mm(self) -> dict[str, np.ndarray]:
        """The setpoints in the PLC, ``{"upper": (rows, cols), "lower": (rows, cols)}`` in mm (what it would drive to)."""
        return self._read_heights_mm("setpoints")

    def read_fault_bits(self) -> dict[str, np.ndarray]:
        """The per-punch fault bits, ``{"upper": (rows, cols) bool, "lower": (rows, cols) bool}``."""
        return {side: np.asarray(bits, dtype=bool) for side, bits in self._fault_bits().items()}

    def _read_heights_mm(self, kind: str) -> dict[str, np.ndarray]:
        """One block of tip heights per side (``"actuals"`` or ``"setpoints"``), decoded from counts to mm."""
        out = {}
        for side in SIDES:
            addr, n = self._block(kind, side)
            words = self._io.read_holding(addr, n, max_chunk=self.map.max_read_registers)
            counts = codec.decode_int32(words, self.identity.word_order).reshape(self.press.shape)
            out[side] = codec.counts_to_mm(counts, self.map.count_mm)
        return out

    def _fault_bits(self) -> dict[str, np.ndarray]:
        n = self.press.rows * self.press.cols
        out = {}
        for side in SIDES:
            f = self._field(f"{side}_fault_bits")
            words = self._io.read_holding(f.address, self.map.bit_words_in_use(self.press.rows, self.press.cols),
                                          max_chunk=self.map.max_read_registers)
            out[side] = codec.unpack_bits(words, n).reshape(self.press.shape)
        return out

    def _motion_timeout_s(self, travel: dict) -> float:
        longest = max(float(t.max()) for t in travel.values())
        return 2.0 * motion_time_s(longest, self.press.speed_mm_s, self.press.accel_mm_s2) + 10.0

    def _follow(self, seq: int, crc: int, raw: dict, targets_mm, start_mm, reporter, timeout_s,
                t0: float) -> StepResult:
        """Poll until the PLC reports COMPLETE for our job; then check the actual positions."""
        travel = {side: np.abs(targets_mm[side] - start_mm[side]) for side in SIDES}
        total_mm = float(sum(t.sum() for t in travel.values()))
        timeout_s = self._motion_timeout_s(travel) if timeout_s is None else timeout_s
        reporter.start(f"motion job {seq} (mm of travel)", total=max(total_mm, 1e-9))
        last_progress = last_hb_change = self._clock.now()
        last_hb = raw["plc_heartbeat"]
        self._undone_at_go = raw["refused_setpoint_writes"]
        while True:
            now = self._clock.now()
            ours = (raw["motion_sequence"], raw["motion_crc"]) == (seq, crc)
            if raw["state_name"] == "COMPLETE" and ours:
                break
            self._check_motion(seq, raw, ours, last_hb, targets_mm, reporter)
            if raw["plc_heartbeat"] != last_hb:
                last_hb, last_hb_change = raw["plc_heartbeat"], now
            elif now - last_hb_change > PLC_STALE_S:
                abandon(reporter, "PLC halted")
                self._plc_halted = True  # nothing to release on closing: no program takes commands
                self._stop_after_trouble("PLC heartbeat stale", wait=False)
                raise PressFault(
                    f"job {seq}: the PLC heartbeat stayed at {last_hb} for {now - last_hb_change:.1f} s during "
                    "motion: the PLC program is not running (PLC in STOP mode, or halted); STOP was sent, but "
                    "the PLC may not act on it",
                    hint="stop the press at the machine and check the PLC before anything else",
                )
            if now - t0 > timeout_s:
                abandon(reporter, "timed out")
                self._stop_after_trouble(f"timeout after {timeout_s:.1f} s")
                raise PressFault(f"job {seq}: motion did not end within {timeout_s:.1f} s; STOP was sent",
                                 hint="check the hydraulics and punches; give --timeout for slow moves")
            if now - last_progress >= PROGRESS_S:
                actual = self.read_actuals_mm()
                reporter.update(max(0.0, total_mm - sum(float(np.abs(targets_mm[s] - actual[s]).sum()) for s in SIDES)))
                last_progress = now
            self._clock.sleep(self.poll_s)
            raw = self._status_raw()
        duration = self._clock.now() - t0
        actual = self.read_actuals_mm()
        reporter.update(total_mm - sum(float(np.abs(targets_mm[s] - actual[s]).sum()) for s in SIDES))
        self._check_duration(seq, travel, duration, reporter)
        reporter.finish()
        self._report_undone_writes(seq, reporter)
        return self._check_arrival(seq, raw, targets_mm, actual, duration)

    def _report_undone_writes(self, seq: int, reporter) -> None:
        """Say how many foreign setpoint writes the PLC undid during the job (refused_setpoint_writes grew)."""
        try:
            now = self._status_raw()["refused_setpoint_writes"]
        except (LinkError, PlcError):
            return
        undone = (now - getattr(self, "_undone_at_go", now)) % 65536
        if undone:
            text = (f"job {seq}: the PLC undid setpoint writes in {undone} scan(s) during the motion: another "
                    "master wrote setpoint registers while the press moved (the job's setpoints were kept)")
            self.audit.record(str(self.url), "foreign writes", "undone", job_sha256=self.job_sha256, sequence=seq,
                              detail=text)
            reporter.info(f"WARNING: {text}; find out which master did it")

    def _check_duration(self, seq: int, travel: dict, duration: float, reporter) -> None:
        """A motion that ended far sooner than the press can move is an error: read the press, STOP if it moves
        (the reporter's task is abandoned, never called done)."""
        scale = getattr(self, "motion_time_scale", None)
        if scale is None or self.press is None:
            return
        longest = max(float(t.max()) for t in travel.values())
        fastest_s = motion_time_s(longest, self.press.speed_mm_s, self.press.accel_mm_s2) / scale
        if duration >= TOO_SOON_FRACTION * fastest_s:
            return
        abandon(reporter, "COMPLETE reported too soon, not believed")
        stopped = self._stop_if_moving(f"COMPLETE after {duration:.2f} s for a move of at least {fastest_s:.2f} s")
        self.audit.record(str(self.url), "complete", "too soon", job_sha256=self.job_sha256, sequence=seq,
                          detail=f"{duration:.2f} s for {longest:.1f} mm (at least {fastest_s:.2f} s)")
        raise PressFault(
            f"job {seq}: the PLC reported COMPLETE after {duration:.2f} s, but a move of {longest:.1f} mm takes "
            f"at least {fastest_s:.2f} s on this press: the PLC's COMPLETE cannot be believed; "
            + self._rest_words(stopped),
            hint="check the PLC program against docs/register-map.md (section 3, 'at rest') before the next step")

    def _check_motion(self, seq: int, raw: dict, ours: bool, last_hb: int, targets_mm, reporter) -> None:
        """During motion: anything but EXECUTING our job ends the step (STOP, rest, PressFault)."""
        state = raw["state_name"]
        if state == "EXECUTING" and ours and not 0 < (last_hb - raw["plc_heartbeat"]) % 65536 < 0x8000:
            return
        abandon(reporter, f"ended in state {state}")
        if state == "FAULT":
            self._stop_after_trouble(f"fault: {self.map.fault_text(raw['fault_code'])}")
            raise self._fault_error(seq, raw, targets_mm)
        if state in ("STOPPING", "STOPPED") and ours:
            self._settle()
            cause = self.map.stop_causes.name(raw["stop_cause"])
            who = (f"a STOP request of master 0x{raw['last_stop_master']:08X}" if cause == "STOP_REQUEST"
                   else "the key switch, turned to local" if cause == "REMOTE_DISABLED" else cause)
            self.audit.record(str(self.url), "complete", "stopped", job_sha256=self.job_sha256, sequence=seq,
                              detail=f"stopped by {who}")
            raise PressFault(f"job {seq} was stopped by {who} during the motion; the step did not complete",
                             hint="find out why the press was stopped, then run the step again")
        self._stop_after_trouble("PLC restarted or lost the job")
        raise PressFault(
            f"the PLC restarted (or another master took over) during job {seq}: state {state}, motion job "
            f"{raw['motion_sequence']}, PLC heartbeat {raw['plc_heartbeat']} (was {last_hb}); STOP was sent, the "
            "step did not complete", hint="check the press, then run the step again")

    def _check_arrival(self, seq: int, raw: dict, targets_mm, actual, duration: float) -> StepResult:
        """COMPLETE: the PLC's in_position and the driver's own check of every punch."""
        errors = {s: actual[s] - targets_mm[s] for s in SIDES}
        max_error = max(float(np.abs(e).max()) for e in errors.values())
        off = self._out_of_tolerance(targets_mm, actual)
        if not off and not raw["flags"]["in_position"]:
            raw = self._await_in_position(raw)
        if off or not raw["flags"]["in_position"]:
            stopped = self._stop_if_moving(f"COMPLETE with {len(off)} punch(es) out of position")
            self.audit.record(str(self.url), "complete", "out of tolerance", job_sha256=self.job_sha256, sequence=seq,
                              detail=f"{len(off)} punches; PLC in_position {raw['flags']['in_position']}")
            named = listed(off) if off else "the PLC does not report the punches in position (in_position clear)"
            rest = ("the punches were still moving: " if stopped else "") + self._rest_words(stopped)
            raise PressFault(
                f"job {seq}: the PLC reported COMPLETE with {len(off)} punch(es) not in position within "
                f"{self.press.position_tolerance_mm} mm: {named}; {rest}",
                hint="a punch may be stuck or blocked, or the PLC ends motion before the punches are at rest in "
                     "their band (docs/register-map.md, section 3): inspect before the next step",
            )
        self.audit.record(str(self.url), "complete", "ok", job_sha256=self.job_sha256, sequence=seq,
                          detail=f"max error {max_error:.3f} mm, {duration:.2f} s")
        return StepResult(sequence=seq, target_upper_mm=targets_mm["upper"], target_lower_mm=targets_mm["lower"],
                          actual_upper_mm=actual["upper"], actual_lower_mm=actual["lower"], max_error_mm=max_error,
                          duration_s=duration)

    def _rest_words(self, stopped: bool) -> str:
        """What the message says of the press after :meth:`_stop_if_moving` (only what was read)."""
        if not stopped:
            return "the press was read at rest"
        if self._not_at_rest:
            return "STOP was sent, but the press did not read at rest in time: check it at the machine"
        return "STOP was sent and the press came to rest"

    def _await_in_position(self, raw: dict) -> dict:
        """Every punch in its band by the driver's reading but ``in_position`` still clear: status bits may come
        a few scans after the state; wait up to :data:`LATE_BITS_SCANS` scans for it."""
        deadline = self._clock.now() + LATE_BITS_SCANS * self.identity.scan_time_s + 2 * self.reply_timeout_s
        while not raw["flags"]["in_position"] and self._clock.now() < deadline:
            self._clock.sleep(self._poll_s)
            raw = self._status_raw()
        return raw

    def _out_of_tolerance(self, targets_mm, actual_mm) -> list[str]:
        tol = self.press.position_tolerance_mm + 0.5 * self.map.count_mm
        return [f"{side} punch ({self.press.punch_label(r, c)}) target {targets_mm[side][r, c]:.2f} mm, "
                f"actual {actual_mm[side][r, c]:.2f} mm"
                for side in SIDES for r, c in np.argwhere(np.abs(actual_mm[side] - targets_mm[side]) > tol)]

    def _fault_error(self, seq: int, raw: dict, targets_mm) -> PressFault:
        """The PressFault for a fault seen during motion (names the faulted punches)."""
        text = self.map.fault_text(raw["fault_code"])
        what = (f"the e-stop was pressed during motion ({text})" if raw["flags"]["estop"]
                else f"the PLC faulted during motion: {text}")
        details = ""
        try:
            bits = self._fault_bits()
            actual = self.read_actuals_mm()
            named = [f"{side} punch ({self.press.punch_label(r, c)}) target {targets_mm[side][r, c]:.2f} mm, "
                     f"actual {actual[side][r, c]:.2f} mm" for side in SIDES for r, c in np.argwhere(bits[side])]
            if named:
                details = f"; faulted punches: {listed(named)}"
        except (LinkError, PlcError):  # the report loses its details, never the fault
            details = "; the per-punch fault bits could not be read"
        self.audit.record(str(self.url), "complete", "fault", job_sha256=self.job_sha256, sequence=seq,
                          detail=f"{text}{details}")
        return PressFault(f"job {seq}: {what}; STOP was sent{details}",
                          hint="remove the cause, then 'mppf reset' and run the step again")
