"""The model plate fitted to the measured cycles: effective yield stress and hardening.

Two numbers of the bending law (:class:`mppf.correct.through_thickness.BendingLaw`) are not known for the
plate in the press and are fitted to what the scanner measured: the effective yield stress
(it carries the scatter of the yield stress and of the thickness, which act alike on
springback) and the linear hardening (it sets how much of a small re-press stays). The fit
(:func:`calibrate`, bounded least squares) is made in two stages:

1. **The first measured shape** against the model's (absolute: springback magnitude, mixed with
   what the model does not describe, the edges, the press), at :data:`ABSOLUTE_WEIGHT`, with a
   prior that keeps both numbers near the nominal values when the data say little. The first
   press is the one the plate's material explains best: no correction has yet moved it by more
   or less than the model predicts.
2. **Every shape and every change** from one measured cycle to the next against the model's
   change for the same strokes (the secants: what decides the next correction's gain), fully,
   with each number held within the band the first shape supports (:func:`_shape_band`: the
   first fit, plus or minus the change of the number that moves the first shape by as much as
   its own misfit). Inside that band the changes refine the material; a plate that answers
   a correction several times more or less than the model cannot pull the yield stress (and with
   it the elastic-limit curvature a reverse bend must cross) or the hardening out of it: that
   mismatch is left to the learned response (:mod:`mppf.correct.secant`).

Misfits are compared as heights at the punches (curvature differences integrated back, plane
removed), where the measurement is.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from mppf.correct.memory import loaded_curvatures, replay
from mppf.correct.punch_grid import PunchGrid
from mppf.correct.through_thickness import BendingLaw

ABSOLUTE_WEIGHT = 0.3
"""Weight of each cycle's shape misfit against the cycle-to-cycle changes."""

MISFIT_SCALE_MM = 1.0
"""Height misfit that counts as one standard deviation."""

YIELD_BOUNDS = (0.5, 2.0)
"""Range of the effective yield stress, as factors of the nominal one."""

YIELD_PRIOR = 0.25
"""Relative standard deviation of the effective yield stress around the nominal one."""

HARDENING_PRIOR_MPA = (1000.0, 3000.0)
"""Linear hardening modulus assumed before any data (MPa) and its standard deviation."""

HARDENING_BOUNDS_MPA = (0.0, 20000.0)


@dataclass(frozen=True, eq=False)
class Calibration:
    """The fitted bending law and how well it describes the measured cycles.

    Attributes
    ----------
    law : BendingLaw
    misfit_mm : float
        RMS height misfit of the shapes of the measured cycles (model minus measurement).
    secant_misfit_mm : float
        RMS misfit of the changes between consecutive measured cycles (NaN with one).
    change_mm : float
        RMS measured change between consecutive cycles (NaN with one).
    """

    law: BendingLaw
    misfit_mm: float
    secant_misfit_mm: float = float("nan")
    change_mm: float = float("nan")


def calibrate(grid: PunchGrid, nominal: BendingLaw, cycles, measured_kappa) -> Calibration:
    """Fit the yield stress and hardening of ``nominal`` to the measured cycles.

    Parameters
    ----------
    grid : PunchGrid
    nominal : BendingLaw
        Thickness, elasticity and the nominal yield stress.
    cycles : list of PressedCycle
    measured_kappa : list of (n, 3) float or None
        The measured unloaded curvature of each cycle (None: not measured).

    Returns
    -------
    Calibration
    """
    loaded = loaded_curvatures(grid, cycles)
    sy0 = nominal.yield_stress_mpa
    h0, h_sd = HARDENING_PRIOR_MPA

    def law(p) -> BendingLaw:
        return replace(nominal, yield_stress_mpa=sy0 * p[0], hardening_mpa=h0 + h_sd * p[1])

    def parts(p):
        model = replay(law(p), loaded, cycles).unloaded
        return _misfits(grid, model, measured_kappa)

    def residuals(p):
        absolute, secant = parts(p)
        prior = [(p[0] - 1.0) / YIELD_PRIOR, p[1]]
        return np.concatenate([ABSOLUTE_WEIGHT * absolute / MISFIT_SCALE_MM, secant / MISFIT_SCALE_MM,
                               np.sqrt(max(len(absolute), 1) / 20.0) * np.array(prior)])

    lo = [YIELD_BOUNDS[0], (HARDENING_BOUNDS_MPA[0] - h0) / h_sd]
    hi = [YIELD_BOUNDS[1], (HARDENING_BOUNDS_MPA[1] - h0) / h_sd]
    first = int(grid.active.sum())  # the residuals of the first measured shape

    def first_residuals(p):
        absolute = parts(p)[0][:first]
        prior = [(p[0] - 1.0) / YIELD_PRIOR, p[1]]
        return np.concatenate([ABSOLUTE_WEIGHT * absolute / MISFIT_SCALE_MM,
                               np.sqrt(max(len(absolute), 1) / 20.0) * np.array(prior)])

    # 1. the first shape alone; 2. every shape and change, each number held to the band the first shape supports
    fit = _least_squares(first_residuals, [1.0, 0.0], lo, hi)
    shapes, secants = parts(fit.x)
    if secants.size:
        for i in range(2):
            lo[i], hi[i] = _shape_band(fit, len(shapes[:first]), lo[i], hi[i], i)
        fit = _least_squares(residuals, np.clip(fit.x, lo, hi), lo, hi)
    absolute, secant = parts(fit.x)
    change = _changes(grid, measured_kappa)
    return Calibration(law(fit.x), _rms(absolute), _rms(secant) if secant.size else float("nan"),
                       _rms(change) if change.size else float("nan"))


def _least_squares(residuals, x0, lo, hi):
    """Bounded least squares of ``residuals`` from ``x0`` (the yield factor, the hardening in prior deviations)."""
    from scipy.optimize import least_squares

    return least_squares(residuals, x0=x0, bounds=(lo, hi), diff_step=1e-3, x_scale=[0.05, 0.3], max_nfev=60)


def _shape_band(fit, n_shape: int, lo: float, hi: float, i: int) -> tuple[float, float]:
    """The range of parameter ``i`` the first shape supports: its fit, plus or minus what moves the shape by its misfit.

    Parameters
    ----------
    fit : scipy.optimize.OptimizeResult
        The fit to the first shape: ``fit.fun[:n_shape]`` its weighted height misfits (mm),
        ``fit.jac[:n_shape, i]`` their change per unit of parameter ``i`` (mm).
    n_shape : int
        Number of shape residuals (the active punches).
    lo, hi : float
        The parameter's own bounds.
    i : int
        0 the yield factor, 1 the hardening in prior standard deviations.

    Returns
    -------
    lo, hi : float
        Half width: the shape's RMS misfit over the RMS of its sensitivity (the whole range
        when the shape does not depend on the parameter).
    """
    sens = float(np.sqrt(np.mean(fit.jac[:n_shape, i] ** 2))) if n_shape else 0.0
    misfit = float(np.sqrt(np.mean(fit.fun[:n_shape] ** 2))) if n_shape else 0.0
    half = misfit / sens if sens > 0 else hi - lo
    centre = float(fit.x[i])
    return max(lo, centre - half), min(hi, centre + half)


def _misfits(grid: PunchGrid, model, measured) -> tuple[np.ndarray, np.ndarray]:
    """Height misfits at the active punches: of every measured cycle, and of every change between two."""
    act = grid.active
    absolute, secant, previous = [], [], None
    for k, kappa in enumerate(measured):
        if kappa is None:
            continue
        diff = model[k] - kappa
        absolute.append(grid.heights(diff)[act])
        if previous is not None:
            secant.append(grid.heights(diff - previous)[act])
        previous = diff
    return (np.concatenate(absolute) if absolute else np.zeros(0),
            np.concatenate(secant) if secant else np.zeros(0))


def _changes(grid: PunchGrid, measured) -> np.ndarray:
    """The measured changes between consecutive measured cycles, as heights at the active punches."""
    known = [k for k in measured if k is not None]
    return np.concatenate([grid.heights(b - a)[grid.active]
                           for a, b in zip(known, known[1:])]) if len(known) > 1 else np.zeros(0)


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values**2))) if values.size else float("nan")
