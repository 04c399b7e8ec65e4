"""The simulated PLC's program, its master side: what a write of the master does.

:class:`Commands` is the part of :class:`mppf.sim.plc.program.PlcProgram` that handles a
master's write: a write touching a read-only or unused register is refused as a whole
(READ_ONLY); a write to a setpoint clears ``data_valid``; writing ``job_sequence``
validates (CRC of the setpoint registers, the PLC's stroke limits) and acknowledges the
sequence; a command (GO, STOP, RESET) is checked and run. A refused write is undone and
answered with the register map's exception code and the reason in ``refusal_code``.
"""

from __future__ import annotations

import numpy as np

from mppf.core.errors import InputError
from mppf.drivers.codec import decode_uint32, encode_int32, mm_to_counts, setpoint_crc32

MATRICES = ("upper", "lower")
"""The two punch matrices, in the order of the program's arrays (index 0 = upper)."""


class Commands:
    """The master's writes: protection, validation, GO / STOP / RESET (a mixin of ``PlcProgram``)."""

    def write(self, address: int, values: list[int]) -> int | None:
        """Handle a master write of ``values`` at ``address`` (inside the map).

        Returns
        -------
        int or None
            The Modbus exception code of a refused write (nothing of it is applied), or
            None when it was accepted. A halted program stores every write unchecked.
        """
        m = self.map
        end = address + len(values)
        if self.frozen:  # a halted program: the write lands in memory, no logic acts on it
            self.regs[address:end] = values
            return None
        touched = {f.name: f for f in m.fields.values() if f.address < end and address < f.end}
        covered = sum(min(end, f.end) - max(address, f.address) for f in touched.values())
        if covered < len(values) or any(not f.writable for f in touched.values()):  # a gap or a read-only register
            self.refusal_code = m.fault("READ_ONLY")
            self._publish_status()
            return m.exceptions["read_only"]
        old = self.regs[address:end]
        old_hb = self._get("master_heartbeat")[0]
        self.regs[address:end] = values
        if "master_heartbeat" in touched and self._get("master_heartbeat")[0] != old_hb:
            self._last_master_hb = self._clock()
        if "upper_setpoints" in touched or "lower_setpoints" in touched:
            self.data_valid = False
        refusal = None
        if "job_sequence" in touched:
            refusal = self._validate()
        if refusal is None and "command" in touched:
            refusal = self._command(self._get("command")[0], self._get("command_arg")[0])
        if refusal is not None:
            self.regs[address:end] = old
            self.refusal_code = m.fault(refusal)
            self._publish_status()
            return m.exceptions["refused"]
        self._publish_status()
        return None

    def write_foreign_setpoint(self, matrix: str, row: int, col: int, value_mm: float) -> int | None:
        """Change one setpoint register as a foreign master would (no CRC update); see :meth:`write`."""
        if matrix not in MATRICES:
            raise InputError(f"matrix must be 'upper' or 'lower', got {matrix!r}")
        field = self.map[f"{matrix}_setpoints"]
        index = self.map.punch_index(row, col, self.press.cols)
        words = encode_int32(mm_to_counts([value_mm], self.map.count_mm), self.word_order)
        return self.write(field.address + 2 * index, words)

    def _validate(self) -> str | None:
        """The master wrote ``job_sequence``: check CRC and limits, acknowledge."""
        sequence = self._get("job_sequence")[0]
        if sequence == 0:
            return "SEQUENCE_MISMATCH"
        if not self._crc_ok():
            return "CRC_MISMATCH"
        if not self._limits_ok():
            return "LIMIT"
        self.ack_sequence = sequence
        self.data_valid = True
        return None

    def _command(self, code: int, arg: int) -> str | None:
        m = self.map
        if code == m.command("STOP"):
            self.hydraulics.stop()
            self._motion_faults = []
        elif code == m.command("RESET"):
            if self.estop_pressed:
                return "ESTOP_ACTIVE"
            self.fault_code = 0
            self.punch_faults[:] = False
        elif code == m.command("GO"):
            refusal = self._go_refusal(arg)
            if refusal is not None:
                return refusal
            if not (self.busy and arg == self.motion_sequence):  # a repeated GO does nothing
                self._start_motion(arg)
        elif code != m.commands.get("NONE", 0):
            return "BAD_COMMAND"
        self.refusal_code = 0
        return None

    def _go_refusal(self, arg: int) -> str | None:
        if self.estop_pressed:
            return "ESTOP_ACTIVE"
        if self.fault_code:
            return "FAULT_ACTIVE"
        if self.busy:
            return None if arg == self.motion_sequence else "BUSY"
        if not self._crc_ok():
            return "CRC_MISMATCH"
        if not self._limits_ok():
            return "LIMIT"
        if arg == 0 or arg != self.ack_sequence:
            return "SEQUENCE_MISMATCH"
        if not self.data_valid:
            return "NOT_VALIDATED"
        return None

    def _start_motion(self, sequence: int) -> None:
        self.goal_mm = self._setpoints_mm()
        self.hydraulics.move_to(self.goal_mm)
        self.motion_sequence = sequence
        self.busy = True
        self.motion_time_s = 0.0
        self._arrived_at_s = None
        self._motion_started_at = self._clock()

    # -- checks --
    def _crc_ok(self) -> bool:
        crc = setpoint_crc32(self._setpoint_words("upper"), self._setpoint_words("lower"))
        return int(decode_uint32(self._get("setpoint_crc"), self.word_order)[0]) == crc

    def _limits_ok(self) -> bool:
        sp = self._setpoints_mm()
        for k, side in enumerate(MATRICES):
            lim = getattr(self.press, side)
            lo = mm_to_counts(lim.min_mm, self.map.count_mm) * self.map.count_mm
            hi = mm_to_counts(lim.max_mm, self.map.count_mm) * self.map.count_mm
            if np.any(sp[k] < lo - 1e-9) or np.any(sp[k] > hi + 1e-9):
                return False
        return True
