"""The simulated PLC's program, its master side: STOP, the owner's lease, the command mailbox.

:class:`Commands` is the part of :class:`mppf.sim.plc.program.PlcProgram` that reads what the
masters wrote, once per scan:

- ``stop_request`` (step 3 of the scan): STOP from anyone, in every state; the PLC writes
  the register back to 0 and counts it;
- the heartbeat (step 4): a beat of the owner (its id, a counter newer than its last
  accepted beat's, the auth computed with the owner's nonce) renews the lease; a lease older
  than the watchdog time ends the ownership (during motion: fault WATCHDOG); the key switch
  turned to local stops a motion;
- the mailbox (step 5): a new (``command_counter``, ``command_master``, ``command_auth``)
  triple is one command; its refusals are tested in the order of the register map's ``checks`` and the
  first that applies is the result; the result, the pair and the command are copied into the
  acknowledgement registers, and, for a command carrying the owner's valid auth (or an
  accepted CLAIM), into the owner's acknowledgement registers, which no other master's
  command changes. CLAIM draws a new nonce, published only as ``claim_reply`` = nonce XOR
  the claim key, and the claim key is cleared from the mailbox in the same scan.

VALIDATE checks, besides the CRC and the stroke limits, the neighbour step (two neighbouring
punches of one matrix: the smaller of the difference of their setpoints and of their moves at
most the PLC's dimpling limit) and the
tip gap of every pair (upper - lower at least the PLC's minimum); parked pairs (both tips at
their park heights) are left out of both.
"""

from __future__ import annotations

import secrets

import numpy as np

from mppf.drivers.codec import auth_crc32, setpoint_crc32

MATRICES = ("upper", "lower")
"""The two punch matrices, in the order of the program's arrays (index 0 = upper)."""

SEQUENCE_WINDOW = 32767
"""A new sequence is newer than the last when (new - last) mod 65536 is 1..SEQUENCE_WINDOW."""


class Commands:
    """STOP, lease and mailbox of the PLC program (a mixin of ``PlcProgram``)."""

    def _reset_commands(self) -> None:
        """Power-on values of everything the masters' commands act on."""
        self.owner = 0
        self.nonce = 0
        self.claim_reply = 0
        self._owner_counter: int | None = None  # command_counter of the owner's last command
        self._beat_counter: int | None = None  # heartbeat_counter of the owner's last accepted beat
        self.owner_ack = (0, 0, 0)  # counter, command, result code of the owner's last command
        self.refused_setpoint_writes = 0
        self._beat_at = 0.0
        self._hb_seen = (0, 0, 0)
        self._last_command = (0, 0, 0)
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
        self.validated = (0, 0)  # STOP always drops the validated job
        if self.state == "EXECUTING":
            self.state = "STOPPING"
            self.hydraulics.stop()
        elif self.state in ("IDLE", "LOADED", "VALIDATED", "COMPLETE"):
            self.state = "STOPPED"
            self.validated = (0, 0)
        if self.hydraulics.moving:  # whatever still moves brakes (also in COMPLETE, STOPPED or FAULT)
            self.hydraulics.stop()

    # ------------------------------------------------------------------ lease ---
    def _lease_fresh(self) -> bool:
        return self.watchdog_s is None or self._clock() - self._beat_at <= self.watchdog_s

    @staticmethod
    def _newer(counter: int, last: int | None) -> bool:
        return last is None or 1 <= (counter - last) % 65536 <= SEQUENCE_WINDOW

    def _check_lease(self) -> None:
        first, count = self.map.span("heartbeat_counter", "heartbeat_master")
        seen = (self._word("heartbeat_counter"), self._u32("heartbeat_master"), self._u32("heartbeat_auth"))
        if seen != self._hb_seen:
            self._hb_seen = seen
            counter, master, auth = seen
            if (self.owner and master == self.owner and self._newer(counter, self._beat_counter)
                    and auth == auth_crc32(self.nonce, self.regs[first: first + count])):
                self._beat_counter = counter
                self._beat_at = self._clock()
                self.beats.append(self._beat_at)
        if self.owner and not self._lease_fresh():
            self._end_lease()
            if self.state == "EXECUTING":
                self._latch("WATCHDOG", halt=False)
            elif self.state in ("LOADED", "VALIDATED"):
                self._drop_job("IDLE")
        if not self.remote_key and self.state == "EXECUTING":
            self._stop("REMOTE_DISABLED")

    def _end_lease(self) -> None:
        """No owner: the nonce is forgotten."""
        self.owner, self.nonce, self.claim_reply = 0, 0, 0

    def _drop_job(self, state: str) -> None:
        self.state = state
        self.validated = (0, 0)

    # ---------------------------------------------------------------- mailbox ---
    def _handle_mailbox(self) -> None:
        pair = (self._word("command_counter"), self._u32("command_master"))
        if pair + (self._u32("command_auth"),) == self._last_command:
            return
        self._last_command = pair + (self._u32("command_auth"),)
        code = self._word("command")
        name = self.map.commands.name(code)
        from_owner = self._auth_ok(pair[1])
        refusal = "BAD_COMMAND" if name is None else next(
            (check for check in self.map.commands.by_name[name].checks if self._refuses(check, name, pair[1])),
            None)
        if refusal is None:
            getattr(self, f"_do_{name.lower()}")(pair[1])
        result = self.map.results.code(refusal or "ACCEPTED")
        self.ack = (pair[0], pair[1], code, result)
        a = self.map["command"].address
        self._quirk_taken(self.regs[a: self.map["command_sequence"].end], str(name), refusal or "ACCEPTED")
        if from_owner or (name == "CLAIM" and refusal is None):
            self._owner_counter = pair[0]
            self.owner_ack = (pair[0], code, result)
        if name == "CLAIM":
            self._set_u32("command_crc", 0)  # the claim key is readable for one scan at most

    def _auth_ok(self, master: int) -> bool:
        """The mailbox carries the owner's id, a counter newer than its last and the auth of its nonce."""
        if not self.owner or master != self.owner:
            return False
        a = self.map["command"].address
        words = self.regs[a: self.map["command_auth"].address] + [self._word("command_sequence")]
        return self._newer(self._word("command_counter"), self._owner_counter) and \
            self._u32("command_auth") == auth_crc32(self.nonce, words)

    def _token(self) -> tuple[int, int]:
        return self._word("command_sequence"), self._u32("command_crc")

    def _refuses(self, check: str, command: str, master: int) -> bool:
        """Whether refusal ``check`` applies to ``command`` from ``master`` now."""
        if check == "BAD_MASTER":
            return master == 0
        if check == "NOT_OWNER":
            return master != self.owner
        if check == "BAD_AUTH":
            return self._u32("command_crc") == 0 if command == "CLAIM" else not self._auth_ok(master)
        if check == "OWNED_BY_OTHER":
            return self.owner != 0 and not self._auth_ok(master)
        if check == "ESTOP_ACTIVE":
            return self.estop_pressed
        if check == "FAULT_ACTIVE":
            return self.state == "FAULT"
        if check == "WRONG_STATE":
            return command not in self.map.states.by_name[self.state].commands
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
        if check == "NEIGHBOUR_STEP":
            return self.neighbour_step_mm() > self.dimpling_limit_mm + 1e-6
        if check == "TIP_GAP":
            return self.min_tip_gap_mm() < self.tip_gap_min_mm - 1e-6
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

    def _parked(self) -> np.ndarray:
        """(rows, cols) bool: pairs whose upper and lower setpoints both stand at their park heights."""
        sp, tol = self._copy_mm(), self.press.position_tolerance_mm
        return (np.abs(sp[0] - self.press.upper.park_mm) <= tol) & (np.abs(sp[1] - self.press.lower.park_mm) <= tol)

    def neighbour_step_mm(self) -> float:
        """Largest neighbour step of the unparked punches of one matrix (mm).

        The neighbour step of two neighbouring punches is the smaller of the difference of their
        setpoints (pressed from a flat plate) and the difference of their moves, setpoint minus
        actual position at VALIDATE (pressed on from where the punches stand): a job must be a
        lawful step from one or the other.
        """
        sp = self._copy_mm()
        move = sp - self.hydraulics.position
        free = ~self._parked()
        worst = 0.0
        for k in range(2):
            for axis in (0, 1):
                a = [slice(None), slice(None)]
                b = [slice(None), slice(None)]
                a[axis], b[axis] = slice(1, None), slice(None, -1)
                both = free[tuple(a)] & free[tuple(b)]
                if both.any():
                    step = np.minimum(np.abs(sp[k][tuple(a)] - sp[k][tuple(b)]),
                                      np.abs(move[k][tuple(a)] - move[k][tuple(b)]))
                    worst = max(worst, float(step[both].max()))
        return worst

    def min_tip_gap_mm(self) -> float:
        """Smallest upper - lower setpoint of the unparked pairs (mm; inf when every pair is parked)."""
        sp, free = self._copy_mm(), ~self._parked()
        return float((sp[0] - sp[1])[free].min()) if free.any() else float("inf")

    # -------------------------------------------------------------- commands ---
    def _do_none(self, master: int) -> None:
        pass

    def _do_claim(self, master: int) -> None:
        self.owner = master
        self.nonce = secrets.randbits(32) or 1
        self.claim_reply = self.nonce ^ self._u32("command_crc")
        self._beat_counter = None
        self._beat_at = self._clock()

    def _do_release(self, master: int) -> None:
        self._end_lease()
        if self.state in ("LOADED", "VALIDATED"):
            self._drop_job("IDLE")

    def _do_validate(self, master: int) -> None:
        self.validated = self._token()
        self.last_sequence = self.validated[0]
        self.state = "VALIDATED"

    def _do_go(self, master: int) -> None:
        self.motion = self.validated
        self.goal_mm = self._copy_mm()
        if not self._quirk_go():
            self.hydraulics.move_to(self.goal_mm)
        self.state = "EXECUTING"
        self.motion_time_s = 0.0
        self._took_go = True

    def _do_reset(self, master: int) -> None:
        self.fault_code = 0
        self.punch_faults[:] = False
        self._drop_job("IDLE")
