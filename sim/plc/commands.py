"""The simulated PLC's program, its master side: STOP, the owner's lease, the command mailbox.

:class:`Commands` is the part of :class:`mppf.sim.plc.program.PlcProgram` that reads what the
masters wrote, once per scan:

- ``stop_request`` (step 3 of the scan): STOP from anyone, in every state; the PLC writes
  the register back to 0 and counts it;
- the heartbeat (step 4): a changed ``heartbeat_counter`` with ``heartbeat_master`` = the
  owner renews the lease; a lease older than the watchdog time ends the ownership (during
  motion: fault WATCHDOG); the key switch turned to local stops a motion;
- the mailbox (step 5): a new (``command_counter``, ``command_master``) pair is one
  command; its refusals are tested in the order of the register map's ``checks`` and the
  first that applies is the result; the result, the pair and the command are copied into the
  acknowledgement registers. Which commands a state accepts is the map's state table.
"""

from __future__ import annotations

from mppf.drivers.codec import setpoint_crc32

MATRICES = ("upper", "lower")
"""The two punch matrices, in the order of the program's arrays (index 0 = upper)."""

SEQUENCE_WINDOW = 32767
"""A new sequence is newer than the last when (new - last) mod 65536 is 1..SEQUENCE_WINDOW."""


class Commands:
    """STOP, lease and mailbox of the PLC program (a mixin of ``PlcProgram``)."""

    def _reset_commands(self) -> None:
        """Power-on values of everything the masters' commands act on."""
        self.owner = 0
        self._beat_at = 0.0
        self._hb_seen = (0, 0)
        self._last_command = (0, 0)
        self.ack = (0, 0, 0, 0)  # counter, master, command, result code
        self.validated = (0, 0)  # sequence, crc
        self.motion = (0, 0)
        self.last_sequence = 0
        self.refused_writes = 0
        self.stop_count = 0
        self.last_stop_master = 0
        self.stop_cause = "NONE"

    # ------------------------------------------------------------------- STOP ---
    def _handle_stop_request(self) -> None:
        if self._word("stop_request") == 0:
            return
        self.stop_count = (self.stop_count + 1) & 0xFFFF
        self.last_stop_master = self._u32("stop_master")
        self._set("stop_request", [0])
        self._stop("STOP_REQUEST")

    def _stop(self, cause: str) -> None:
        """STOP: a motion brakes (STOPPING), a job is dropped (STOPPED); FAULT stays FAULT."""
        self._motion_faults = []
        self.stop_cause = cause
        if self.state == "EXECUTING":
            self.state = "STOPPING"
            self.hydraulics.stop()
        elif self.state in ("IDLE", "LOADED", "VALIDATED", "COMPLETE"):
            self.state = "STOPPED"
            self.validated = (0, 0)
        elif self.hydraulics.moving:  # STOPPING, STOPPED or FAULT: brake whatever still moves
            self.hydraulics.stop()

    # ------------------------------------------------------------------ lease ---
    def _lease_fresh(self) -> bool:
        return self.watchdog_s is None or self._clock() - self._beat_at <= self.watchdog_s

    def _check_lease(self) -> None:
        seen = (self._u32("heartbeat_master"), self._word("heartbeat_counter"))
        if seen != self._hb_seen:
            self._hb_seen = seen
            if self.owner and seen[0] == self.owner:
                self._beat_at = self._clock()
                self.beats.append(self._beat_at)
        if self.owner and not self._lease_fresh():
            self.owner = 0
            if self.state == "EXECUTING":
                self._latch("WATCHDOG", halt=False)
            elif self.state in ("LOADED", "VALIDATED"):
                self._drop_job("IDLE")
        if not self.remote_key and self.state == "EXECUTING":
            self._stop("REMOTE_DISABLED")

    def _drop_job(self, state: str) -> None:
        self.state = state
        self.validated = (0, 0)

    # ---------------------------------------------------------------- mailbox ---
    def _handle_mailbox(self) -> None:
        pair = (self._word("command_counter"), self._u32("command_master"))
        if pair == self._last_command:
            return
        self._last_command = pair
        code = self._word("command")
        name = self.map.commands.name(code)
        refusal = "BAD_COMMAND" if name is None else next(
            (check for check in self.map.commands.by_name[name]["checks"] if self._refuses(check, name, pair[1])),
            None)
        if refusal is None:
            getattr(self, f"_do_{name.lower()}")(pair[1])
        self.ack = (pair[0], pair[1], code, self.map.results.code(refusal or "ACCEPTED"))

    def _token(self) -> tuple[int, int]:
        return self._word("command_sequence"), self._u32("command_crc")

    def _refuses(self, check: str, command: str, master: int) -> bool:
        """Whether refusal ``check`` applies to ``command`` from ``master`` now."""
        if check == "BAD_MASTER":
            return master == 0
        if check == "NOT_OWNER":
            return master != self.owner
        if check == "OWNED_BY_OTHER":
            return self.owner not in (0, master)
        if check == "ESTOP_ACTIVE":
            return self.estop_pressed
        if check == "FAULT_ACTIVE":
            return self.state == "FAULT"
        if check == "WRONG_STATE":
            return command not in self.map.states.by_name[self.state]["commands"]
        if check == "REMOTE_DISABLED":
            return not self.remote_key
        if check == "SEQUENCE_REUSED":
            return not 1 <= (self._token()[0] - self.last_sequence) % 65536 <= SEQUENCE_WINDOW
        if check == "TOKEN_MISMATCH":
            return self._token() != self.validated
        if check == "CRC_MISMATCH":
            return self._token()[1] != setpoint_crc32(self._copy["upper"], self._copy["lower"])
        if check == "LIMIT":
            return not self._limits_ok()
        raise AssertionError(f"no test for refusal {check}")

    def _limits_ok(self) -> bool:
        sp = self._copy_mm()
        count = self.map.count_mm
        for k, side in enumerate(MATRICES):
            lim = getattr(self.press, side)
            lo, hi = round(lim.min_mm / count) * count, round(lim.max_mm / count) * count
            if sp[k].min() < lo - 1e-9 or sp[k].max() > hi + 1e-9:
                return False
        return True

    # -------------------------------------------------------------- commands ---
    def _do_none(self, master: int) -> None:
        pass

    def _do_claim(self, master: int) -> None:
        self.owner = master
        self._beat_at = self._clock()

    def _do_release(self, master: int) -> None:
        self.owner = 0
        if self.state in ("LOADED", "VALIDATED"):
            self._drop_job("IDLE")

    def _do_validate(self, master: int) -> None:
        self.validated = self._token()
        self.last_sequence = self.validated[0]
        self.state = "VALIDATED"

    def _do_go(self, master: int) -> None:
        self.motion = self.validated
        self.goal_mm = self._copy_mm()
        self.hydraulics.move_to(self.goal_mm)
        self.state = "EXECUTING"
        self.motion_time_s = 0.0
        self._arrived_at_s = None

    def _do_reset(self, master: int) -> None:
        self.fault_code = 0
        self.punch_faults[:] = False
        self._drop_job("IDLE")
