"""The motion part of the simulated PLC's program: the PLC's own settings, "at rest", the end of a motion.

:class:`Motion` is the part of :class:`mppf.sim.plc.program.PlcProgram` that runs step 6 of the
scan (docs/register-map.md, section 3): the hydraulics advance by the scan's simulated time; a
punch is at rest once it has stood still for the rest time; EXECUTING becomes COMPLETE only
with every punch at rest in its band (a punch out of its band latches STUCK_PUNCH after the
positioning timeout, :mod:`mppf.sim.plc.program_faults`), STOPPING becomes STOPPED at rest.
"""

from __future__ import annotations

import math

import numpy as np

from mppf.core.errors import InputError

MAX_STEP_S = 0.02
"""Longest integration step of the motion (simulated s)."""
MAX_STEPS_PER_SCAN = 50
"""Coarser steps rather than a scan that falls further and further behind."""


class Motion:
    """Settings, rest and the end of motion of the PLC program (a mixin of ``PlcProgram``)."""

    def _configure(self, limits: dict) -> None:
        """The PLC's own configuration: positioning timeout, rest threshold, neighbour step, tip gap."""
        known = {"positioning_timeout_s": 2.0, "rest_speed_mm_s": 0.5, "rest_time_s": 0.05, "tip_gap_min_mm": 5.0}
        unknown = sorted(set(limits) - set(known))
        if unknown:
            raise InputError(f"unknown PLC setting {unknown[0]!r}", hint=f"known: {', '.join(known)}")
        for key, default in known.items():
            value = limits.get(key, default)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and 0 <= value <= 65.0):
                raise InputError(f"PLC setting {key} must be a number from 0 to 65, got {value!r}")
            setattr(self, key, float(value))
        self.dimpling_limit_mm = float(self.press.max_neighbour_diff_mm)

    def _run_motion(self, dt_s: float) -> None:
        """Advance the hydraulics by the scan's simulated time; end motion when every punch is at rest."""
        sim_dt = dt_s * self.time_scale
        steps = min(max(1, math.ceil(sim_dt / MAX_STEP_S - 1e-9)), MAX_STEPS_PER_SCAN)
        for _ in range(steps):
            self.hydraulics.step(sim_dt / steps)
            self._still_s = 0.0 if self.hydraulics.moving else self._still_s + sim_dt / steps
            if self.state != "EXECUTING":
                continue
            self.motion_time_s += sim_dt / steps
            self._run_motion_faults()
            if self.frozen:  # the program halted in this step: this scan publishes its last image
                return
        if self._quirk_end_of_motion():
            return
        if self.state == "EXECUTING" and self.at_rest:
            self._check_stuck()
            if self.state == "EXECUTING" and self.in_band:
                self.state = "COMPLETE"
        elif self.state == "STOPPING" and self.at_rest:
            self.state = "STOPPED"

    @property
    def at_rest(self) -> bool:
        """Every punch slower than the rest speed for the rest time (the map's definition, speed part)."""
        return not self.hydraulics.moving and self._still_s >= self.rest_time_s - 1e-9

    @property
    def in_band(self) -> bool:
        """Every punch within the position tolerance of its goal."""
        return bool(np.all(np.abs(self.hydraulics.position - self.goal_mm) <= self.press.position_tolerance_mm))
