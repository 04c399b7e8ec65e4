"""What the plate went through: every pressed step of every cycle, and the model plate pressed the same way.

:class:`PressedCycle` is one cycle as the press did it (the tips read back after each step it
completed; a step interrupted during its motion last, its share of the way unknown) and as
the scanner measured it. :func:`replay` presses the model's bending law (:mod:`mppf.correct.through_thickness`)
at every punch through the same steps in the same order, so the model plate carries the
same plastic memory as the real one: what it was bent to, where it yielded, where it would
yield again.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.correct.punch_grid import PunchGrid
from mppf.correct.through_thickness import BendingLaw, BendingState

SHARES = np.linspace(0.1, 1.0, 10)
"""Shares of its way an interrupted step may have gone, tried by :func:`interrupted_share`."""


@dataclass(frozen=True, eq=False)
class PressedCycle:
    """One cycle of a plate as pressed and measured.

    Attributes
    ----------
    steps_mid_mm : list of (rows, cols) float
        The loaded mid heights ``(upper + lower) / 2`` of every step the press did, in
        order, from the tips read back (NaN where inactive).
    error_mm : (rows, cols) float or None
        The deviation measured at the punches after the cycle (positive = plate above the
        design, plane removed; NaN where unknown); None when the cycle was not measured.
    interrupted : bool
        The last step was stopped during its motion (its share of the way is unknown; its
        mid heights are the setpoints it was moving towards).
    share : float or None
        The share of its way the interrupted step went, when known (fitted to the scan by
        :func:`interrupted_share`).
    """

    steps_mid_mm: list
    error_mm: np.ndarray | None
    interrupted: bool = False
    share: float | None = None

    @property
    def measured(self) -> bool:
        return self.error_mm is not None and bool(np.isfinite(self.error_mm).any())


@dataclass(frozen=True, eq=False)
class Replay:
    """The model plate after each cycle: unloaded curvature (n, 3), plastic state, last loaded curvature (n, 3)."""

    unloaded: list
    states: list
    loaded: list


def loaded_curvatures(grid: PunchGrid, cycles) -> list[list[np.ndarray]]:
    """Loaded curvature (m, 3) at the active punches of every step of every cycle (of the tips' mid heights)."""
    return [[grid.curvature(mid) for mid in c.steps_mid_mm] for c in cycles]


def replay(law: BendingLaw, loaded, cycles) -> Replay:
    """The model plate pressed through every step of every cycle, from flat and stress free.

    Parameters
    ----------
    law : BendingLaw
    loaded : list of list of (n, 3) float
        :func:`loaded_curvatures` of the cycles.
    cycles : list of PressedCycle
        For the shares of interrupted steps (an unknown share counts as the whole way).
    """
    n = loaded[0][0].shape[0]
    state, unloaded, last = BendingState.virgin(n), np.zeros((n, 3)), np.zeros((n, 3))
    out = Replay([], [], [])
    for steps, cycle in zip(loaded, cycles):
        for index, kappa in enumerate(steps):
            if cycle.interrupted and index == len(steps) - 1 and cycle.share is not None:
                kappa = last + cycle.share * (kappa - last)  # stopped on its way
            unloaded, state = law.press(kappa, state)
            last = kappa
        out.unloaded.append(unloaded)
        out.states.append(state)
        out.loaded.append(last)
    return out


def interrupted_share(law: BendingLaw, grid: PunchGrid, loaded, cycles, measured_kappa) -> list:
    """The cycles with the share of each interrupted step fitted to its scan (or 1: the whole way).

    The share is the one of :data:`SHARES` whose model plate is nearest the measured one
    (curvature misfit over the active punches).
    """
    out = list(cycles)
    for k, cycle in enumerate(cycles):
        if not cycle.interrupted or cycle.share is not None:
            continue
        if measured_kappa[k] is None:
            out[k] = _with_share(cycle, 1.0)
            continue
        costs = []
        for share in SHARES:
            trial = out[: k] + [_with_share(cycle, float(share))]
            unloaded = replay(law, loaded[: k + 1], trial).unloaded[-1]
            costs.append(float(np.sum(np.nan_to_num(grid.heights(unloaded - measured_kappa[k])) ** 2)))
        out[k] = _with_share(cycle, float(SHARES[int(np.argmin(costs))]))
    return out


def _with_share(cycle: PressedCycle, share: float) -> PressedCycle:
    return PressedCycle(cycle.steps_mid_mm, cycle.error_mm, cycle.interrupted, share)
