"""The learned correction: the next strokes from everything the press and the scanner measured.

:func:`learned_correction` is the loop's correction as a short sequence of steps:

1. the model plate (:mod:`mppf.correct.through_thickness`, one per punch) is pressed through every step
   the press did, in order (:func:`mppf.correct.memory.replay`), with the share of an
   interrupted step fitted to its scan;
2. its yield stress and hardening are fitted to the first measured shape, then to every
   measured cycle, above all to the changes from cycle to cycle, within the band the first
   shape supports (:func:`mppf.correct.calibrate.calibrate`);
3. the plate's response is compared with the model's on every measured secant and the
   difference learned in smooth modes (:class:`mppf.correct.secant.ModeGain`, Broyden);
4. the plate is aimed at ``aim`` of the way to the design (short of it: an over-bent plate
   needs a reverse bend, an under-bent one only more of the same), the outer rows aimed
   between their own deviation and the net plate's edge beyond them when it is known
   (:func:`mppf.correct.edge.balanced_error`), the model asked for that change divided by
   the learned response;
5. the loaded curvature that gives it is found point by point through the model with its
   memory (:func:`mppf.correct.invert.invert`: crossing what stays elastic, reverse bending
   where the plate is over-bent), integrated to strokes, in a few virtual cycles on the
   model (:func:`mppf.correct.solve.solve_change`), inside a trust region in curvature
   (the size of the step asked for is the step policy's, :mod:`mppf.correct.policy`);
6. what the model cannot make (more than half of the wanted change left) gets the classic
   displacement adjustment (:func:`_direct_part`);
7. the strokes are held to the stroke limits; :func:`steps_towards` splits the way from the
   tips the plate last held into steps within the dimpling limit.

The measured deviation carries what no model describes (the residual): the model gives
only the change, so what it gets wrong about the plate's shape does not enter the step.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from mppf.core.grid import largest_neighbour_difference
from mppf.correct.calibrate import Calibration, calibrate
from mppf.correct.edge import balanced_error
from mppf.correct.inputs import CorrectedPlate
from mppf.correct.memory import PressedCycle, interrupted_share, loaded_curvatures, replay
from mppf.correct.punch_grid import PunchGrid
from mppf.correct.secant import ModeGain
from mppf.correct.solve import STALLED, solve_change
from mppf.correct.through_thickness import BendingLaw
from mppf.model.job_parts import StepStrokes
from mppf.model.press import PressConfig

AIM = (0.92, 0.95)
"""Share of the way to the design aimed at: by the first correction, and once a secant is known
(short of the design: an over-bent region needs a reverse bend, an under-bent one only more of
the same)."""

DIRECT_GAIN = 0.7
"""Gain of the displacement adjustment on what the model step cannot make."""

REACH_ELASTIC_LIMITS = 4.0
"""Trust region of one correction: the loaded curvature may change by at most this many
elastic-limit curvatures at any punch (the model is trusted that far from what was pressed)."""

MIN_REACH_ELASTIC_LIMITS = 2.5
"""The smallest reach, however small the trust region: a reverse bend must cross the elastic
stretch of the plate's memory (two elastic-limit curvatures) to change anything at all."""


@dataclass(frozen=True, eq=False)
class LearnedCorrection:
    """The next strokes and what the correction learned.

    Attributes
    ----------
    upper_mm, lower_mm : (rows, cols) float
        The next cycle's final strokes (NaN where inactive).
    n_steps : int
        Steps needed from the plate's last tips within the dimpling limit.
    change_mm : (rows, cols) float
        Added to both matrices (0 where inactive).
    predicted_mm : (rows, cols) float
        Deviation expected after pressing them (NaN where inactive).
    calibration : Calibration
    gains : (m,) float
        Singular values of the learned response ratio (1: as the model).
    unreached : (rows, cols) bool
        Punches whose wanted change lies beyond the trust region.
    clipped : (rows, cols) bool
        Punches held to the stroke limits.
    notes : list of str
    """

    upper_mm: np.ndarray
    lower_mm: np.ndarray
    n_steps: int
    change_mm: np.ndarray
    predicted_mm: np.ndarray
    calibration: Calibration
    gains: np.ndarray
    unreached: np.ndarray
    clipped: np.ndarray
    notes: list = field(default_factory=list)

    @property
    def predicted_rms_mm(self) -> float:
        """RMS of the deviation expected after pressing the strokes (mm)."""
        values = self.predicted_mm[np.isfinite(self.predicted_mm)]
        return float(np.sqrt(np.mean(values**2))) if values.size else float("nan")


def learned_correction(plate: CorrectedPlate, cycles, base_upper_mm, base_lower_mm, *, trust: float = 1.0,
                       edge_mm=None, scale=None) -> LearnedCorrection:
    """The next strokes from every pressed and measured cycle of the plate.

    Parameters
    ----------
    plate : CorrectedPlate
        The press, the design's mid-surface heights at the punches, thickness, nominal material, active punches.
    cycles : list of PressedCycle
        Every cycle so far, the last one measured.
    base_upper_mm, base_lower_mm : (rows, cols) float
        The strokes to correct (the last cycle's final step as planned), NaN where inactive.
    trust : float
        Size of the trust region, in (0, 1]: scales the reach in curvature and the share of the
        way aimed at (the loop leaves it at 1 and sizes the step by ``scale``).
    edge_mm : (rows, cols) float, optional
        The deviation of the net plate's edge beyond the outer-row punches after the last
        cycle (:func:`mppf.measure.punches.edge_deviations`): near the design those punches
        are aimed between their own deviation and the edge's (:func:`mppf.correct.edge.balanced_error`).
    scale : (rows, cols) float, optional
        Share of the wanted change asked for at each punch (:attr:`mppf.correct.policy.StepPlan.share`);
        default 1.
    """
    press = plate.press
    grid = PunchGrid(press, plate.active)
    # 1-2. the plate model through every step the press did, fitted to what the scanner measured
    law, calibration, cycles, model = _fitted_model(grid, plate, cycles)
    # 3. the plate's response against the model's, learned on every secant
    gain = _learn_response(grid, model, cycles)
    # 4. the change wanted of the plate, and what to ask of the model for it
    error = grid.flat(np.where(grid.active, balanced_error(cycles[-1].error_mm, edge_mm), np.nan))
    error = np.where(grid.active & np.isfinite(error), error, 0.0)
    aim = (AIM[1] if gain.updates else AIM[0]) * (0.5 + 0.5 * trust)
    wanted = error if scale is None else error * np.where(grid.active, np.asarray(scale, dtype=float), 1.0)
    request = gain.model_request(-aim * wanted)
    # 5. the loaded curvature for it, through the model with its memory, in virtual cycles
    base_mid = 0.5 * (np.asarray(base_upper_mm, dtype=float) + np.asarray(base_lower_mm, dtype=float))
    reach = (MIN_REACH_ELASTIC_LIMITS + (REACH_ELASTIC_LIMITS - MIN_REACH_ELASTIC_LIMITS) * trust) \
        * law.elastic_limit_per_mm
    largest = _stroke_room(press)
    change, misfit, unreached = solve_change(grid, law, model.states[-1], model.unloaded[-1], base_mid, request,
                                             reach, largest)
    # 6. what the model cannot make (a local error it does not describe): the displacement adjustment
    direct = trust * _direct_part(grid, law, model, base_mid, change, request, misfit)
    # 7. the strokes, held to the limits, and the steps they need
    found = _Found(change + direct, error, gain, law, model, calibration, unreached, aim, direct)
    return _strokes(press, grid, base_upper_mm, base_lower_mm, found)


def _fitted_model(grid: PunchGrid, plate: CorrectedPlate, cycles):
    """The model plate pressed through every cycle, its yield stress and hardening fitted to the measured ones.

    Returns the fitted law, the :class:`Calibration`, the cycles with the share of an interrupted
    step fitted to its scan, and the model replayed through them (:func:`mppf.correct.memory.replay`).
    """
    design = np.where(grid.active, plate.design_mid_mm, np.nan)
    # 1. what the scanner measured, as curvatures of the plate at the punches
    measured = [grid.curvature(design + c.error_mm) if c.measured else None for c in cycles]
    nominal = plate.nominal
    law = BendingLaw(plate.thickness_mm, nominal.youngs_modulus_mpa, nominal.poisson, nominal.yield_stress_mpa)
    loaded = loaded_curvatures(grid, cycles)
    cycles = interrupted_share(law, grid, loaded, cycles, measured)
    # 2. the model plate's yield stress and hardening from the measured cycles
    calibration = calibrate(grid, law, cycles, measured)
    law = calibration.law
    cycles = interrupted_share(law, grid, loaded, [_unknown_share(c) for c in cycles], measured)
    return law, calibration, cycles, replay(law, loaded, cycles)


class _Found(NamedTuple):
    """What the correction found (:func:`learned_correction` steps 1-6), for :func:`_strokes`; grids (rows, cols) mm."""

    change: np.ndarray  # the stroke change of both matrices, the direct part included
    error: np.ndarray  # the deviation aimed at (0 where unknown)
    gain: ModeGain
    law: BendingLaw
    model: object  # the replayed model plate (:func:`mppf.correct.memory.replay`)
    calibration: Calibration
    unreached: np.ndarray  # bool: the wanted change lies beyond the trust region
    aim: float
    direct: np.ndarray  # the displacement adjustment's part of ``change``


def _direct_part(grid: PunchGrid, law: BendingLaw, model, base_mid, change, request, misfit: float) -> np.ndarray:
    """The displacement adjustment of what the model step leaves, when it leaves much (else 0).

    Where the model finds no stroke change that makes the plate change as wanted (a local
    error at the plate's edge, a region the per-punch model does not describe), the strokes
    there move by :data:`DIRECT_GAIN` of what is still missing, as the classic displacement
    adjustment does (the plate is assumed to follow the tips one to one there).
    """
    act = grid.active
    wanted = np.where(act, request, 0.0)
    if misfit <= STALLED * float(np.sqrt(np.mean(wanted[act] ** 2))):
        return np.zeros(grid.shape)
    kappa = grid.curvature(np.where(act, base_mid + change, np.nan))
    made = grid.heights(law.press(kappa, model.states[-1])[0] - model.unloaded[-1])
    return np.where(act, DIRECT_GAIN * (wanted - np.where(act, made, 0.0)), 0.0)


def _stroke_room(press: PressConfig) -> float:
    """Largest stroke change the press allows (mm): the trust region is in curvature, not in stroke.

    Scaling a stroke change down as a whole can leave all of it inside the elastic range
    of a plate bent near its elastic limit (no change at all): so the stroke change is held
    only by the press, its curvature per punch by :data:`REACH_ELASTIC_LIMITS`.
    """
    return float(min(press.upper.max_mm - press.upper.min_mm, press.lower.max_mm - press.lower.min_mm))


def _unknown_share(cycle: PressedCycle) -> PressedCycle:
    return PressedCycle(cycle.steps_mid_mm, cycle.error_mm, cycle.interrupted, None)


def _learn_response(grid: PunchGrid, model, cycles) -> ModeGain:
    """Broyden updates of the plate's response from every pair of consecutive measured cycles."""
    gain = ModeGain(grid)
    known = [k for k, c in enumerate(cycles) if c.measured]
    for j, k in zip(known, known[1:]):
        model_change = grid.heights(model.unloaded[k] - model.unloaded[j])
        plate_change = grid.flat(np.where(grid.active, cycles[k].error_mm - cycles[j].error_mm, np.nan))
        gain.update(model_change, plate_change)
    return gain


def _strokes(press: PressConfig, grid: PunchGrid, base_upper, base_lower, found: _Found) -> LearnedCorrection:
    """The corrected strokes within the stroke limits, their steps and the expected deviation."""
    change, error, gain, law, model, calibration, unreached, aim, direct = found
    act = grid.active
    upper = np.where(act, np.asarray(base_upper, dtype=float) + change, np.nan)
    lower = np.where(act, np.asarray(base_lower, dtype=float) + change, np.nan)
    clipped = act & ((upper > press.upper.max_mm) | (upper < press.upper.min_mm) | (lower > press.lower.max_mm)
                     | (lower < press.lower.min_mm))
    shift = np.clip(lower, press.lower.min_mm, press.lower.max_mm) - lower
    shift = np.where(act, shift + np.clip(upper + shift, press.upper.min_mm, press.upper.max_mm) - (upper + shift), 0.0)
    upper, lower, change = upper + shift, lower + shift, np.where(act, change + shift, 0.0)
    n_steps = max(1, int(np.ceil(largest_neighbour_difference(change, act) / press.max_neighbour_diff_mm - 1e-9)))
    kappa = grid.curvature(0.5 * (upper + lower))
    made = grid.heights(law.press(kappa, model.states[-1])[0] - model.unloaded[-1])
    predicted = np.where(act, error + gain.plate_response(made) + direct, np.nan)
    notes = [f"plate model calibrated on {sum(1 for k in model.unloaded)} cycle(s): effective yield stress "
             f"{law.yield_stress_mpa:.0f} MPa, hardening {law.hardening_mpa:.0f} MPa; shape misfit "
             f"{calibration.misfit_mm:.2f} mm RMS", f"aim {aim:.0%} of the way; learned response "
             f"{', '.join(f'{g:.2f}' for g in gain.gains[:3])} ({gain.updates} secant(s))"]
    if np.any(direct != 0.0):
        notes.append(f"the model step left much of the error: displacement adjustment on the rest "
                     f"(largest {np.max(np.abs(direct)):.1f} mm)")
    return LearnedCorrection(upper, lower, n_steps, change, predicted, calibration, gain.gains, unreached, clipped,
                             notes)


def steps_towards(press: PressConfig, held, learned: LearnedCorrection, active) -> list[StepStrokes]:
    """Steps from the held tips to the learned strokes, each within the dimpling limit (k/N of the way).

    Parameters
    ----------
    press : PressConfig
    held : tuple of (rows, cols) float
        The upper and lower tips the plate was last held between (read back), or the flat plate's.
    learned : LearnedCorrection
    active : (rows, cols) bool

    Returns
    -------
    list of StepStrokes
        The last one is ``learned``'s strokes.
    """
    act = np.asarray(active, dtype=bool)
    up0, lo0 = (np.where(act, np.asarray(h, dtype=float), 0.0) for h in held)
    travel_up = np.where(act, learned.upper_mm - up0, 0.0)
    travel_lo = np.where(act, learned.lower_mm - lo0, 0.0)
    worst = max(largest_neighbour_difference(travel_up, act), largest_neighbour_difference(travel_lo, act))
    n = max(1, int(np.ceil(worst / press.max_neighbour_diff_mm - 1e-9)))
    return [StepStrokes(np.where(act, up0 + travel_up * k / n, np.nan), np.where(act, lo0 + travel_lo * k / n, np.nan),
                        act) for k in range(1, n + 1)]
