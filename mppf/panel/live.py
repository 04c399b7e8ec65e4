"""The live press as the panel shows it: successive PLC readings turned into states, marks and progress.

:class:`LiveTracker` follows the readings of one press: a punch **lags** when the press is
moving and the punch has stood still for :data:`LAG_S` short of its target (every punch
of the simulated and the real press moves at the same speed until it arrives, so one
standing short of its target is held back); the mark stays until the next motion starts.
A punch is **faulted** when the PLC sets its fault bit. The progress of a motion is the
share of the travel left at its start that is done. :func:`press_state` names the state
in one word. Pure: arrays and numbers in, JSON-ready dicts out.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from mppf.panel.svg import punch_name

SIDES = ("upper", "lower")
LAG_S = 0.5
"""A punch short of its target that has not moved for this long while the press moves lags."""

STILL_MM = 0.02
"""Movement between two readings below this counts as standing still (the counts are 0.01 mm)."""

HEARTBEAT_STALE_S = 1.0
"""The PLC heartbeat unchanged this long: the PLC program is not running."""

MAX_FLAGGED = 24
"""Marked punches listed by name at most (all are marked in the maps)."""


STATE_WORDS = {"EXECUTING": "MOVING", "STOPPING": "STOPPING", "STOPPED": "STOPPED", "FAULT": "FAULT"}
"""The PLC states (register map version 2) shown as they are; the others as READY / NOT READY."""


def press_state(flags: dict | None, link_ok: bool, plc_state: str = "") -> str:
    """One word for the press: LINK LOST, E-STOP, FAULT, MOVING, STOPPING, STOPPED, READY or NOT READY.

    (The panel says NO PLC before it knows of any PLC.)

    Parameters
    ----------
    flags : dict of str to bool or None
        The status bits (``estop``, ``fault``, ``busy``, ``ready``).
    link_ok : bool
    plc_state : str
        The PLC's state name (``"EXECUTING"``, ``"STOPPED"``...).
    """
    if not link_ok or flags is None:
        return "LINK LOST"
    if flags.get("estop"):
        return "E-STOP"
    if flags.get("fault") or plc_state == "FAULT":
        return "FAULT"
    if plc_state in STATE_WORDS:
        return STATE_WORDS[plc_state]
    if flags.get("busy"):
        return "MOVING"
    return "READY" if flags.get("ready") else "NOT READY"


@dataclass
class _SideTrack:
    last_mm: np.ndarray
    still_since_s: np.ndarray
    lagging: np.ndarray


@dataclass
class LiveTracker:
    """Marks and progress from successive readings of one press.

    Parameters
    ----------
    tolerance_mm : float
        |target - actual| accepted as on target (the press's position tolerance).
    base : int
        First row / column number of the punch names.
    """

    tolerance_mm: float
    base: int = 1
    _sides: dict = field(default_factory=dict)
    _busy: bool = False
    _motion_start_s: float = 0.0
    _travel_mm: float = 0.0
    _heartbeat: int | None = None
    _heartbeat_since_s: float = 0.0

    def update(self, t_s: float, busy: bool, targets: dict, actuals: dict, faulted: dict) -> dict:
        """Take one reading; return the marks and the progress.

        Parameters
        ----------
        t_s : float
            Time of the reading (s, monotonic).
        busy : bool
            The PLC's ``busy`` bit.
        targets, actuals : dict of str to (rows, cols) float
            Setpoints and actual tip heights per side (mm).
        faulted : dict of str to (rows, cols) bool
            Per-punch fault bits (empty dict: none read).

        Returns
        -------
        dict
            ``flags`` (side to (rows, cols) list of "", "lagging", "faulted"), ``flagged``
            (named punches, faulted first), ``progress_pct`` (None outside a motion that
            was seen starting) and ``moving``.
        """
        started = busy and not self._busy
        if started:
            self._motion_start_s = t_s
            self._travel_mm = sum(float(np.abs(targets[s] - actuals[s]).sum()) for s in SIDES)
        self._busy = busy
        flags, flagged = {}, []
        for side in SIDES:
            track = self._track(side, t_s, actuals[side], started)
            remaining = np.abs(targets[side] - actuals[side])
            if busy and t_s - self._motion_start_s >= LAG_S:
                track.lagging |= (remaining > self.tolerance_mm) & (t_s - track.still_since_s >= LAG_S)
            fault = np.asarray(faulted.get(side, np.zeros(remaining.shape, bool)), dtype=bool)
            grid = np.where(fault, "faulted", np.where(track.lagging, "lagging", ""))
            flags[side] = grid.tolist()
            for r, c in np.argwhere(grid != ""):
                flagged.append({"side": side, "name": f"{side} {punch_name(r, c, self.base)}", "kind": grid[r, c],
                                "target_mm": round(float(targets[side][r, c]), 2),
                                "actual_mm": round(float(actuals[side][r, c]), 2)})
        flagged.sort(key=lambda f: f["kind"] != "faulted")
        return {"flags": flags, "flagged": flagged[:MAX_FLAGGED], "n_flagged": len(flagged),
                "progress_pct": self._progress(busy, targets, actuals), "moving": busy}

    def _track(self, side: str, t_s: float, actual: np.ndarray, started: bool) -> _SideTrack:
        track = self._sides.get(side)
        if track is None or track.last_mm.shape != actual.shape:
            track = _SideTrack(actual.copy(), np.full(actual.shape, t_s), np.zeros(actual.shape, bool))
            self._sides[side] = track
        moved = np.abs(actual - track.last_mm) > STILL_MM
        track.still_since_s = np.where(moved, t_s, track.still_since_s)
        track.last_mm = actual.copy()
        if started:
            track.lagging[:] = False
        return track

    def _progress(self, busy: bool, targets: dict, actuals: dict) -> float | None:
        if self._travel_mm <= 0.0:
            return None
        left = sum(float(np.abs(targets[s] - actuals[s]).sum()) for s in SIDES)
        return round(100.0 * min(1.0, max(0.0, 1.0 - left / self._travel_mm)), 1)

    def heartbeat_stale(self, t_s: float, heartbeat: int) -> bool:
        """True when the PLC heartbeat has not changed for :data:`HEARTBEAT_STALE_S`."""
        if heartbeat != self._heartbeat:
            self._heartbeat, self._heartbeat_since_s = heartbeat, t_s
        return t_s - self._heartbeat_since_s > HEARTBEAT_STALE_S


def grid_json(values) -> list:
    """A (rows, cols) float grid as nested lists rounded to 0.01 mm (NaN as None)."""
    arr = np.round(np.asarray(values, dtype=float), 2)
    return [[None if not np.isfinite(v) else float(v) for v in row] for row in arr]
