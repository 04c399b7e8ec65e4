"""The owner's side of the command mailbox: CLAIM with a claim key, auth words, the owner's acknowledgement.

:class:`Mailbox` is the part of :class:`mppf.drivers.session.PlcSession` that sends commands
(register map 3, section 5 and 7 of docs/register-map.md): the mailbox written in one request
with the auth word of the PLC's nonce, the wait for the acknowledgement in the owner's own
registers (no other master's command changes them), and CLAIM, RELEASE and RESET. The nonce
comes back from CLAIM as ``claim_reply`` XOR the claim key and is kept in memory only.
"""

from __future__ import annotations

import os

from mppf.core.errors import PressRefused
from mppf.drivers import codec
from mppf.drivers.audit import Audited


def new_master_id() -> int:
    """A random 32-bit number, never 0 (a master id per session; a claim key per CLAIM)."""
    return int.from_bytes(os.urandom(4), "big") or 1


class Mailbox:
    """Commands of the owner (a mixin of ``PlcSession``)."""

    # ----------------------------------------------------------------- mailbox ---
    def _send(self, name: str, *, sequence: int = 0, crc: int = 0) -> int:
        """Write the mailbox with the auth of the nonce (one request, one attempt, never retried); the counter."""
        self._counter = self._counter % 0xFFFF + 1
        order = self.identity.word_order
        head = [self.map.command(name), self._counter] + codec.u32_to_words(self.master_id, order)
        head += codec.u32_to_words(crc, order)
        auth = codec.auth_crc32(self._nonce, head + [sequence])
        self._io.write_command(self.map["command"].address, head + codec.u32_to_words(auth, order) + [sequence])
        self._sent_code = self.map.command(name)
        return self._counter

    def _acknowledged(self, raw: dict, counter: int) -> dict | None:
        """The status with ``result_code`` of this master's command ``counter``, once the PLC took it.

        The owner's acknowledgement registers are looked at first (no other master's command
        changes them); the shared ones only name a command of this master that the PLC refused
        before it knew us as the owner (a refused CLAIM).
        """
        ours = raw["owner_ack_counter"] == counter and raw["owner_ack_command"] == getattr(self, "_sent_code", None)
        if ours and raw["owner_master"] in (self.master_id, 0):  # 0: our RELEASE accepted (no owner now)
            return dict(raw, result_code=raw["owner_result_code"])
        if raw["ack_counter"] == counter and raw["ack_master"] == self.master_id:
            return raw
        return None

    def _await_ack(self, counter: int) -> dict | None:
        """Poll until the PLC acknowledges ``counter`` of this master; the status then, or None on timeout."""
        deadline = self._clock.now() + self.ack_timeout_s
        while True:
            raw = self._acknowledged(self._status_raw(), counter)
            if raw is not None:
                return raw
            if self._clock.now() >= deadline:
                return None
            self._clock.sleep(self._poll_s)

    def _command(self, name: str, *, sequence: int = 0, crc: int = 0) -> dict:
        """Send a command and wait for its acknowledgement; return the status read with it.

        Raises
        ------
        PressRefused
            No acknowledgement within :attr:`ack_timeout_s`.
        LinkError, PlcError
        """
        raw = self._await_ack(self._send(name, sequence=sequence, crc=crc))
        if raw is None:
            raise PressRefused(
                f"the PLC at {self.url} did not acknowledge {name} within {self.ack_timeout_s:.1f} s",
                hint="check that the PLC program runs ('mppf status': plc_heartbeat counts) and that no other "
                     "master writes the command mailbox")
        return raw

    def _result(self, raw: dict) -> str:
        return self.map.results.name(raw["result_code"]) or f"result {raw['result_code']}"

    # -------------------------------------------------------------- ownership ---
    def claim(self) -> None:
        """Own the PLC (CLAIM) and start the heartbeat; nothing is written while another master owns it.

        Raises
        ------
        PressRefused
            Another master holds a live lease, or the PLC refused the claim.
        LinkError, PlcError
        """
        raw = self._status_raw()
        owner, lease_ok = raw["owner_master"], raw["flags"]["lease_ok"]
        if owner == self.master_id and lease_ok and self._nonce:
            self._owner = True
            self._start_heartbeat()
            return
        if owner not in (0, self.master_id) and lease_ok:
            self.audit.record(str(self.url), "claim", "not sent", job_sha256=self.job_sha256,
                              detail=f"owned by master 0x{owner:08X}")
            raise PressRefused(f"the PLC at {self.url} is owned by master 0x{owner:08X}, whose lease is alive: "
                               "another master is driving the press; nothing was written",
                               hint="wait until it has finished (see 'mppf status'), or stop it with 'mppf stop'")
        key = new_master_id()  # the claim key: any 32-bit number but 0
        with Audited(self, "claim", detail=f"master 0x{self.master_id:08X}") as row:
            self._nonce = 0
            raw = self._command("CLAIM", crc=key)
            if not raw["result_code"]:
                self._nonce = raw["claim_reply"] ^ key
            else:
                row.outcome, row.detail = "refused", self.map.result_text(raw["result_code"])
                raise PressRefused(f"the PLC at {self.url} refused CLAIM: {row.detail}; nothing was written",
                                   hint="wait until the other master has finished (see 'mppf status')")
        self._owner = True
        self._start_heartbeat()

    def release(self) -> None:
        """Give the PLC back (RELEASE) and stop the heartbeat; refused (and recorded) while it moves."""
        if not self._owner:
            return
        try:
            with Audited(self, "release") as row:
                raw = self._command("RELEASE")
                if raw["result_code"]:
                    row.outcome, row.detail = "refused", self.map.result_text(raw["result_code"])
        finally:
            self._owner = False
            self._stop_heartbeat()

    def reset(self) -> None:
        """Reset latched faults and drop the job (claims the PLC first; on request only).

        Raises
        ------
        PressRefused
            Another master owns the PLC, or the PLC refused (e.g. the e-stop is still pressed).
        LinkError
        """
        self.claim()
        with Audited(self, "reset") as row:
            raw = self._command("RESET")
            if raw["result_code"]:
                row.outcome, row.detail = "refused", self.map.result_text(raw["result_code"])
                raise PressRefused(f"the PLC at {self.url} refused RESET: {row.detail}",
                                   hint="remove the cause (release the e-stop), then reset again")
