"""STOP, RESET, and leaving the press safe when a step goes wrong.

:class:`Safety` is the part of :class:`mppf.drivers.plc_press.PlcPress` that commands
STOP (one attempt, never retried) and RESET (on request only), and decides what is sent
after trouble: STOP once on a fault, timeout, Ctrl-C (again on a fresh connection when
Ctrl-C interrupts the STOP itself), a lost link (after reconnecting) or a refusal by the
PLC after GO. A failed STOP is recorded, never hidden, and the original trouble raised.
"""

from __future__ import annotations

from mppf.core.errors import LinkError, PlcError, PressRefused

RECONNECT_S = 2.0  # how long to try reconnecting after a lost link before sending STOP
STOP_ATTEMPTS_AFTER_CTRL_C = 3  # a STOP interrupted by another Ctrl-C is sent again, this often at most


class Safety:
    """STOP, RESET and the reactions to trouble during a step (a mixin of ``PlcPress``)."""

    def _refusal_text(self) -> str:
        try:
            code = self._read_field("refusal_code")[0]
        except (LinkError, PlcError):  # the refusal is reported either way, its reason if it can be read
            return "reason unknown (refusal_code could not be read)"
        return self.map.fault_text(code)

    def stop(self, reason: str = "operator request") -> None:
        """Command STOP (one attempt, never retried; the PLC always accepts it).

        Raises
        ------
        LinkError
            STOP could not be delivered.
        PlcError
            The PLC refused it (a PLC that is not an mppf press PLC).
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

    def _reconnect(self, within_s: float = RECONNECT_S) -> None:
        """Open a fresh connection, trying for up to ``within_s`` seconds."""
        deadline = self._clock.now() + within_s
        while True:
            self._io.close()
            try:
                self._io.connect()
                return
            except LinkError:
                if self._clock.now() >= deadline:
                    raise
                self._clock.sleep(0.1)

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
            except (LinkError, PlcError):  # only the extra detail is lost
                pass
        except (LinkError, PlcError):  # STOP could not be delivered (no link) or was refused
            self._record("stop", "failed", sequence=seq, detail=f"no link: {exc.message}")
            state = "STOP could not be sent: stop the press at the machine"
        return LinkError(f"link to the PLC lost during job {seq} after GO: {exc.message}; {state}",
                         hint="check the press and the link, then run the step again")
