"""Injectable faults and machine inputs of the simulated PLC's program.

:class:`ProgramFaults` is the fault part of :class:`mppf.sim.plc.program.PlcProgram`: the
injected conditions (stuck punch, e-stop, overpressure, halted program, key switch turned
to local), the timers that trigger them a given time into the motion, how they latch, and
the machine's inputs an operator changes at the press (releasing the e-stop, the
remote-enable key switch). The faults of the link (slow replies, dropped connections,
restarts) are the Modbus server's (:mod:`mppf.sim.plc.server`). The grammar of ``--fault``
specs is :mod:`mppf.sim.faults`.
"""

from __future__ import annotations

import numpy as np

from mppf.core.errors import InputError
from mppf.sim.faults import KINDS
from mppf.sim.plc.commands import MATRICES

PROGRAM_FAULTS = ("stuck", "estop", "overpressure", "freeze", "local")
"""Faults of the PLC program (the rest of :data:`mppf.sim.faults.KINDS` act on the link)."""


class ProgramFaults:
    """Fault injection, fault timers and machine inputs of the PLC program (a mixin of ``PlcProgram``).

    Attributes
    ----------
    estop_pressed : bool
        The e-stop circuit is open (until :meth:`release_estop` or :meth:`clear_faults`).
    frozen : bool
        The program is halted: no scan, writes land in memory unacted.
    remote_key : bool
        The remote-enable key switch is in remote (set with :meth:`set_remote`).
    """

    def _init_faults(self) -> None:
        self.estop_pressed = False
        self.frozen = False
        self._motion_faults: list[tuple[float, str]] = []  # (after simulated s of motion, kind)
        self._stuck_fault_after_s: dict[tuple[int, int, int], float] = {}

    def inject(self, kind: str, **params) -> None:
        """Inject a fault of the program (see docs/simulator.md).

        Parameters
        ----------
        kind : {"stuck", "estop", "overpressure", "freeze", "local"}
        **params
            stuck: ``matrix`` ("upper"/"lower"), ``row``, ``col`` (0-based), ``percent`` (of
            each move done before it sticks, default 50), ``fault_after_s`` (simulated s
            after every punch came to rest until fault STUCK_PUNCH and the punch's fault
            bit; None: the PLC's positioning timeout). estop / overpressure / freeze /
            local (key switch to local): ``after_s`` (simulated s into the motion of the
            current or next GO; None: now).

        Raises
        ------
        InputError
            Unknown fault, a fault of the link, or bad parameters.
        """
        if kind not in PROGRAM_FAULTS:
            if kind in KINDS:
                raise InputError(f"fault {kind!r} acts on the Modbus link, which this PLC program does not have",
                                 hint="inject it into a simulated PLC served over Modbus "
                                      "(mppf.sim.plc.run_simulated_plc)")
            raise InputError(f"unknown fault {kind!r}", hint=f"known faults: {', '.join(KINDS)}")
        try:
            if kind == "stuck":
                self._inject_stuck(**params)
            else:
                self._inject_timed(kind, **params)
        except TypeError as exc:
            raise InputError(f"fault {kind!r}: {exc}", hint="see docs/simulator.md for the parameters") from None
        self.publish()

    def _inject_stuck(self, matrix, row, col, percent=50.0, fault_after_s=None) -> None:
        if matrix not in MATRICES:
            raise InputError(f"stuck punch: matrix must be 'upper' or 'lower', got {matrix!r}")
        if not (0 <= row < self.press.rows and 0 <= col < self.press.cols):
            raise InputError(
                f"stuck punch: row {row}, col {col} outside the {self.press.rows} x {self.press.cols} matrix",
                hint="rows and columns count from 0 here (the register order)",
            )
        if not 0 <= percent <= 100:
            raise InputError(f"stuck punch: percent must be 0..100, got {percent}")
        idx = (MATRICES.index(matrix), int(row), int(col))
        self.hydraulics.set_stuck(idx, percent / 100.0)
        if fault_after_s is not None:
            self._stuck_fault_after_s[idx] = float(fault_after_s)

    def _inject_timed(self, kind, after_s=None) -> None:
        if after_s is None:
            self._trigger(kind)
        else:
            self._motion_faults.append((float(after_s), kind))

    def _trigger(self, kind: str) -> None:
        if kind == "freeze":
            self.frozen = True
            self.hydraulics.halt()  # outputs off: the valves close
        elif kind == "estop":
            self.estop_pressed = True  # the e-stop circuit cuts the valves at once
            self._latch("ESTOP")
        elif kind == "overpressure":
            self._latch("OVERPRESSURE")
        elif kind == "local":
            self.remote_key = False  # seen by the next scan: a motion stops

    def _run_motion_faults(self) -> None:
        """Trigger the faults whose time of motion has come."""
        for after_s, kind in list(self._motion_faults):
            if self.motion_time_s >= after_s:
                self._motion_faults.remove((after_s, kind))
                self._trigger(kind)

    def _read_inputs(self) -> None:
        """Scan step 1: an open e-stop circuit latches ESTOP in any state."""
        if self.estop_pressed and self.state != "FAULT":
            self._latch("ESTOP")

    def _check_stuck(self) -> None:
        """EXECUTING, every punch at rest: a punch outside its band for the positioning timeout latches
        STUCK_PUNCH with the fault bits of the punches outside their band."""
        if self.fault_code:
            return
        timeout_s = min(self._stuck_fault_after_s.values(), default=self.positioning_timeout_s)
        off = np.abs(self.hydraulics.position - self.goal_mm) > self.press.position_tolerance_mm
        if off.any() and self._still_s >= timeout_s:
            self.punch_faults[off] = True
            self._latch("STUCK_PUNCH")

    # ------------------------------------------------------ operator inputs ---
    def release_estop(self) -> None:
        """Release a pressed e-stop (the ESTOP fault stays latched until RESET)."""
        self.estop_pressed = False
        self.publish()

    def set_remote(self, remote: bool) -> None:
        """Turn the remote-enable key switch: True = remote (GO allowed), False = local."""
        self.remote_key = bool(remote)
        self.publish()

    def clear_faults(self) -> None:
        """Remove every injected condition of the program (stuck punches, pending triggers, a
        pressed e-stop, a halted program). Latched faults stay until the master sends RESET."""
        self.hydraulics.free_all()
        self._stuck_fault_after_s.clear()
        self._motion_faults = []
        self.estop_pressed = False
        self.frozen = False
        self.publish()
