"""Misbehaviours of a PLC written from a misread register map, and foreign masters at its side.

:class:`Quirks` is the part of :class:`mppf.sim.plc.program.PlcProgram` that lets the
simulated PLC behave as the PLCs and masters that broke earlier drivers did, so that the
driver is tested against them (``mppf sim --quirk ...``, docs/simulator.md):

==========================  ==========================================================
quirk                       behaviour
==========================  ==========================================================
``literal-complete``        the valves open one scan after GO, and EXECUTING ends when
                            "no punch moves" (read literally, not at rest in the band):
                            COMPLETE in the scan of GO while the whole move follows
``late-status:N``           ``status_word`` published N scans late (1..10)
``borrow-ids``              a foreign master copies the readable owner id and validated
                            token: GO as the owner every scan while a job is VALIDATED,
                            and a heartbeat with the owner's id every scan
``none-after-go``           a foreign master writes NONE into the mailbox right after
                            the scan that took a GO (the shared acknowledgement is
                            overwritten)
``foreign-stop[@T]``        a foreign master sends STOP T simulated s into the motion
                            (default 0.5)
==========================  ==========================================================

The foreign masters write into the register image right after a scan, as a Modbus write
landing between two scans would; they know only what any master can read.
"""

from __future__ import annotations

from collections import deque

from mppf.drivers.codec import u32_to_words

from mppf.core.errors import InputError

QUIRKS = ("literal-complete", "late-status", "borrow-ids", "none-after-go", "foreign-stop")
FOREIGN_MASTER = 0xF0E1D2C3
"""The id of the foreign master of ``none-after-go`` and ``foreign-stop``."""
_GRAMMAR = "literal-complete, late-status:N (1..10), borrow-ids, none-after-go, foreign-stop[@T]"


def parse_quirk(spec: str) -> tuple[str, float | None]:
    """``(name, value)`` of one quirk spec (``late-status:2``, ``foreign-stop@0.5``, ...).

    Raises
    ------
    InputError
        An unknown quirk or a bad value (the message names the spec and the grammar).
    """
    text = str(spec).strip().lower()
    name, _, value = text.replace("@", ":").partition(":")
    if name not in QUIRKS:
        raise InputError(f"unknown PLC quirk {spec!r}", hint=f"known quirks: {_GRAMMAR}")
    if name not in ("late-status", "foreign-stop"):
        if value:
            raise InputError(f"PLC quirk {spec!r} takes no value", hint=f"known quirks: {_GRAMMAR}")
        return name, None
    try:
        number = float(value) if value else (None if name == "late-status" else 0.5)
    except ValueError:
        number = None
    if number is None or not (number >= 0 and number < 1e6):
        raise InputError(f"PLC quirk {spec!r}: the value must be a number, got {value!r}", hint=f"known quirks: {_GRAMMAR}")
    if name == "late-status" and not (number == int(number) and 1 <= number <= 10):
        raise InputError(f"PLC quirk {spec!r}: N must be a whole number of scans from 1 to 10, got {value!r}",
                         hint="e.g. late-status:2")
    return name, number


class Quirks:
    """The quirks of the PLC program (a mixin of ``PlcProgram``)."""

    def _init_quirks(self, quirks) -> None:
        self.quirks: dict[str, float | None] = dict(parse_quirk(q) for q in quirks)
        late = int(self.quirks.get("late-status") or 0)
        self._late_words: deque[int] = deque(maxlen=late + 1)
        self._valves_pending = None
        self._foreign_counter = 0
        self._foreign_beat = 0
        self._foreign_stop_due = "foreign-stop" in self.quirks
        self._foreign_words: list[int] | None = None
        self.foreign_results: list[tuple[str, str]] = []  # (command, result) of the foreign masters' commands

    # -------------------------------------------------------- literal-complete ---
    def _quirk_go(self) -> bool:
        """GO of a literal PLC: the valves open at the next scan. True when the move was deferred."""
        if "literal-complete" not in self.quirks:
            return False
        self._valves_pending = self.goal_mm.copy()
        return True

    def _quirk_scan_start(self) -> None:
        """Start of a scan: a literal PLC's valves open for the GO of the scan before."""
        if self._valves_pending is not None:
            self.hydraulics.move_to(self._valves_pending)
            self._valves_pending = None

    def _quirk_end_of_motion(self) -> bool:
        """A literal PLC ends EXECUTING when no punch moves; True when it decided."""
        if "literal-complete" not in self.quirks:
            return False
        if not self.hydraulics.moving:
            if self.state == "EXECUTING":
                self.state = "COMPLETE"
            elif self.state == "STOPPING":
                self.state = "STOPPED"
        return True

    # ------------------------------------------------------------ late status ---
    def _late_status_word(self, word: int) -> int:
        if not self._late_words.maxlen or self._late_words.maxlen == 1:
            return word
        self._late_words.append(word)
        return self._late_words[0]

    def _published_state(self) -> int:
        return self.map.states.code(self.state)

    # -------------------------------------------------------- foreign masters ---
    def _foreign_command(self, name: str, master: int, sequence: int = 0, crc: int = 0) -> None:
        self._foreign_counter = self._foreign_counter % 0xFFFF + 1
        order = self.word_order
        words = ([self.map.command(name), self._foreign_counter] + u32_to_words(master, order)
                 + u32_to_words(crc, order) + [0, 0] + [sequence])
        self.store(self.map["command"].address, words)
        self._foreign_words = words

    def _quirk_taken(self, words: list[int], command: str, result: str) -> None:
        """The mailbox command just taken: recorded when it is a foreign master's."""
        if self._foreign_words is not None and words == self._foreign_words:
            self.foreign_results.append((command, result))
            self._foreign_words = None

    def _quirk_after_scan(self, took_go: bool) -> None:
        """The foreign masters act on what they read right after a scan."""
        q = self.quirks
        if "borrow-ids" in q and self.owner:
            self._foreign_beat = self._foreign_beat % 0xFFFF + 1
            self.store(self.map["heartbeat_counter"].address,
                       [self._foreign_beat] + u32_to_words(self.owner, self.word_order) + [0, 0])
            if self.state == "VALIDATED":  # GO as the owner, with the published token, every scan until it moves
                self._foreign_command("GO", self.owner, *self.validated)
        if "none-after-go" in q and took_go:
            self._foreign_command("NONE", FOREIGN_MASTER)
        if (self._foreign_stop_due and self.state == "EXECUTING"
                and self.motion_time_s >= (q.get("foreign-stop") or 0.0)):
            self._foreign_stop_due = False
            self.store(self.map["stop_request"].address, [1] + u32_to_words(FOREIGN_MASTER, self.word_order))
