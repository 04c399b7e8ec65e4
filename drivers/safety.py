"""Leaving the press safe when a step goes wrong: STOP, the wait for rest, lost links, refusals.

:class:`Safety` is the part of :class:`mppf.drivers.plc_press.PlcPress` that decides what is
sent after trouble: STOP once on a fault, a timeout, a refusal after GO, Ctrl-C (again on a
fresh connection when Ctrl-C interrupts the STOP itself) or a lost link (after
reconnecting); then it waits for the press to come to rest (STOPPED, COMPLETE or a fault at
standstill) while the heartbeat goes on, so that the PLC's watchdog does not turn a
controlled stop into a fault. A failed STOP is recorded, never hidden, and the original
trouble raised.
"""

from __future__ import annotations

from mppf.core.errors import LinkError, PlcError, PressFault

RECONNECT_S = 2.0  # how long to try reconnecting (a connection and a status read) after a lost link
STOP_ATTEMPTS_AFTER_CTRL_C = 3  # a STOP interrupted by another Ctrl-C is sent again, this often at most
SETTLE_MARGIN_S = 2.0  # the wait for rest after STOP: the braking time plus this
REST_READS_MIN = 2  # the actual positions read unchanged this many times in a row count as still


class Safety:
    """The reactions to trouble during a step (a mixin of ``PlcPress``)."""

    def _reconnect(self, within_s: float | None = None) -> None:
        """Open a fresh connection that answers a status read, trying for ``within_s`` s (the map's reconnect time).

        A connection accepted and then reset (a PLC restarting, a gateway) counts as a failed try.
        """
        if within_s is None:
            within_s = self.map.timing.get("reconnect_ms", RECONNECT_S * 1000) / 1000.0
        deadline = self._clock.now() + within_s
        while True:
            self._io.close()
            try:
                self._io.connect()
                self._status_raw()
                return
            except LinkError:
                if self._clock.now() >= deadline:
                    raise
                self._clock.sleep(0.1)

    def _still_mm(self) -> float:
        """Largest change of an actual position between two reads that still counts as standing still."""
        tolerance = self.press.position_tolerance_mm if self.press is not None else 0.2
        return max(tolerance / 2, self.map.count_mm)

    def _rest_time_s(self) -> float:
        return max(self.identity.rest_time_s, 2 * self._poll_s)

    def _await_rest(self, within_s: float | None = None) -> bool:
        """Wait (heartbeat going on) until the press is at rest; True when it is, False when it is not in time.

        At rest: the PLC reports neither EXECUTING/STOPPING nor ``busy``, and the driver's own
        reads of the actual positions have not changed for the PLC's rest time (the driver
        does not take a PLC's word for it). Without a press description the status alone counts.
        """
        if within_s is None:
            brake_s = self.press.speed_mm_s / self.press.accel_mm_s2 if self.press is not None else 1.0
            within_s = brake_s + SETTLE_MARGIN_S + 4 * self.identity.scan_time_s
        deadline = self._clock.now() + within_s
        last, still_since, still_reads, reads = None, None, 0, 0
        while True:
            now = self._clock.now()
            try:
                raw = self._status_raw()
                actual = self.read_actuals_mm() if self.press is not None else None
            except (LinkError, PlcError):
                return False
            quiet = not raw["flags"]["busy"] and raw["state_name"] not in ("EXECUTING", "STOPPING")
            same = actual is None or (last is not None and max(
                float(abs(actual[s] - last[s]).max()) for s in actual) <= self._still_mm())
            if quiet and same:
                still_since = now if still_since is None else still_since
                still_reads += 1
                if still_reads >= REST_READS_MIN and now - still_since >= self._rest_time_s():
                    return True
            else:
                still_since, still_reads = None, 0
            last = actual
            reads += 1
            if now >= deadline and reads > REST_READS_MIN:
                return False
            self._clock.sleep(self.poll_s)

    def _settle(self) -> None:
        """Wait for rest after STOP (kept for the callers that do not need the answer)."""
        self._await_rest()

    def _stop_if_moving(self, reason: str) -> bool:
        """Read the state and the actual positions; STOP and wait for rest when anything may move.

        Returns True when STOP was sent.
        """
        if self._await_rest(within_s=self._rest_time_s() + 2 * self.poll_s):
            return False
        self._stop_after_trouble(reason)
        return True

    def _stop_after_trouble(self, reason: str, *, fresh: bool = False, wait: bool = True) -> None:
        """Send STOP (on a fresh connection if ``fresh``) and wait for rest; a failure is recorded, not raised.

        ``fresh`` is for an interrupted request (Ctrl-C): its reply may still be on the way
        and must not be taken for the reply to STOP. ``wait=False`` for a halted PLC program,
        which takes no STOP and never comes to rest.
        """
        for _ in range(STOP_ATTEMPTS_AFTER_CTRL_C):
            try:
                if fresh:
                    self._reconnect()
                self.stop(reason, wait=wait)
                if wait and not self._await_rest():
                    self.audit.record(str(self.url), "rest", "not reached", job_sha256=self.job_sha256,
                                      sequence=self._last_sequence or None, detail=reason)
                    self._not_at_rest = True
                return
            except (LinkError, PlcError, PressFault):
                return  # recorded by stop(); the caller raises the original trouble
            except KeyboardInterrupt:
                # Ctrl-C again while STOP was on its way: the operator wants the press stopped,
                # so STOP again (harmless to repeat) on a fresh connection
                fresh = True
                reason = f"{reason} (Ctrl-C again: STOP repeated)"
        self.audit.record(str(self.url), "stop", "failed", job_sha256=self.job_sha256,
                          sequence=self._last_sequence or None,
                          detail=f"{reason}: interrupted by Ctrl-C {STOP_ATTEMPTS_AFTER_CTRL_C} times")

    def _refused_after_go(self, exc: PlcError, seq: int) -> PlcError:
        """The PLC refused a request while the press moved: STOP once (the link works), a PlcError."""
        self._stop_after_trouble(f"refusal during motion: {exc.message}")
        error = PlcError(f"job {seq}: {exc.message} while the press moved after GO; STOP was sent",
                         hint="check the PLC ('mppf status'), then run the step again")
        error.exception_code = getattr(exc, "exception_code", None)
        return error

    def _lost_link(self, exc: LinkError, seq: int | None, go_sent: bool) -> LinkError:
        """The link failed during a step: STOP once after reconnecting (if GO was sent)."""
        if not go_sent:
            return LinkError(
                f"link to the PLC lost before GO: {exc.message}; GO was not sent, so this job never started",
                hint="check the link, then run the step again (it uploads and verifies afresh)",
            )
        try:
            self._reconnect()
            self.stop(f"link lost: {exc.message}")
            state = "STOP was sent after reconnecting"
            try:
                raw = self._status_raw()
                if seq is not None and raw["motion_sequence"] != seq:
                    state += (f"; the PLC restarted (it no longer knows job {seq}: state {raw['state_name']}, "
                              f"motion job {raw['motion_sequence']}, PLC heartbeat {raw['plc_heartbeat']})")
                if not self._await_rest():
                    self._not_at_rest = True
            except (LinkError, PlcError):  # only the extra detail is lost
                pass
        except (LinkError, PlcError, PressFault):  # STOP could not be delivered (no link), refused or not taken
            self.audit.record(str(self.url), "stop", "failed", job_sha256=self.job_sha256, sequence=seq,
                              detail=f"no link: {exc.message}")
            state = "STOP could not be sent: stop the press at the machine"
        return LinkError(f"link to the PLC lost during job {seq} after GO: {exc.message}; {state}",
                         hint="check the press and the link, then run the step again")
