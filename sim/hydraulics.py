"""Hydraulic punch motion of the simulated PLC: trapezoidal velocity profiles.

Every punch of both matrices is an axis that accelerates at ``accel_mm_s2`` up to
``speed_mm_s`` toward its target and decelerates so that it stops exactly on it (a
trapezoidal profile, triangular for short moves). A STOP decelerates every axis to a
standstill; an e-stop halts them at once. A stuck punch stops part of the way along
each move. Pure numpy; time is simulated seconds.
"""

from __future__ import annotations

import numpy as np


class Hydraulics:
    """Punch axes of both matrices.

    Parameters
    ----------
    positions_mm : (2, rows, cols) float
        Initial tip heights (index 0 = upper matrix, 1 = lower).
    speed_mm_s, accel_mm_s2 : float
        Largest speed and acceleration of every axis.
    """

    def __init__(self, positions_mm: np.ndarray, speed_mm_s: float, accel_mm_s2: float):
        self.position = np.array(positions_mm, dtype=float)
        self.velocity = np.zeros_like(self.position)
        self.target = self.position.copy()
        self.speed_mm_s = float(speed_mm_s)
        self.accel_mm_s2 = float(accel_mm_s2)
        # stuck punches: fraction of each move after which the axis stops (NaN = free)
        self.stuck_fraction = np.full(self.position.shape, np.nan)

    @property
    def moving(self) -> bool:
        """True while any axis has not come to rest."""
        return bool(np.any(self.velocity != 0.0) or np.any(self.position != self.target))

    def move_to(self, target_mm: np.ndarray) -> None:
        """Start moving every axis toward ``target_mm`` (2, rows, cols)."""
        target = np.array(target_mm, dtype=float)
        stuck = ~np.isnan(self.stuck_fraction)
        partway = self.position + np.nan_to_num(self.stuck_fraction) * (target - self.position)
        self.target = np.where(stuck, partway, target)

    def set_stuck(self, index: tuple[int, int, int], fraction: float) -> None:
        """Make axis ``index`` (matrix, row, col) stop at ``fraction`` of each move.

        A move already under way stops at that fraction of what remains of it.
        """
        self.stuck_fraction[index] = fraction
        remaining = self.target[index] - self.position[index]
        self.target[index] = self.position[index] + fraction * remaining

    def free_all(self) -> None:
        """Free every stuck axis (it moves on at the next :meth:`move_to`)."""
        self.stuck_fraction[:] = np.nan

    def stop(self) -> None:
        """Decelerate every axis to a standstill at the acceleration limit."""
        brake_mm = self.velocity * np.abs(self.velocity) / (2.0 * self.accel_mm_s2)
        self.target = self.position + brake_mm

    def halt(self) -> None:
        """Stop every axis at once (valves closed: e-stop, overpressure)."""
        self.velocity[:] = 0.0
        self.target = self.position.copy()

    def step(self, dt_s: float) -> None:
        """Advance the motion by ``dt_s`` simulated seconds."""
        if not self.moving:  # every axis at rest on its target: nothing changes (an idle PLC's every scan)
            return
        a, vmax = self.accel_mm_s2, self.speed_mm_s
        gap = self.target - self.position
        direction = np.sign(gap)
        distance = np.abs(gap)
        speed_toward = self.velocity * direction
        # fastest end-of-step speed v' from which the axis can still stop on the target
        # after this step's travel (v + v') dt / 2:  v'^2 <= 2 a (distance - (v + v') dt / 2)
        adt = a * dt_s
        room = np.maximum(2.0 * a * distance - adt * speed_toward, 0.0)
        allowed = np.minimum(vmax, 0.5 * (-adt + np.sqrt(adt * adt + 4.0 * room)))
        new_speed = np.clip(allowed, speed_toward - a * dt_s, speed_toward + a * dt_s)
        new_speed = np.maximum(new_speed, 0.0)
        travel = 0.5 * (np.maximum(speed_toward, 0.0) + new_speed) * dt_s
        arrived = (travel >= distance) | (distance == 0.0)
        self.position = np.where(arrived, self.target, self.position + direction * travel)
        self.velocity = np.where(arrived, 0.0, direction * new_speed)
