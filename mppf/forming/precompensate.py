"""Springback pre-compensation by virtual press cycles on the plate model.

The planner's first guess over-bends the design's principal arcs (:mod:`mppf.planning.overbend`).
That guess is uniform over the plate: it misses where the curvature varies (saddles,
flares) and the plate's edges, where the plate between the outer punches and the edge is
not held (:mod:`mppf.forming.plate_model`: the loaded plate is the least-bending surface through
the contact points). Before anything is pressed, :func:`refine_strokes` therefore runs the
shop's own correction loop on the plate model with the NOMINAL material: predict the
sprung-back plate from the strokes, measure its deviation from the design at every punch,
correct the strokes (:func:`mppf.correct.compensate.compensate`, the same springback-model step the
real loop uses), and repeat until the predicted deviation is below ``tolerance_mm``. This
is the simulation-based displacement adjustment of die design, done per plate.

What it cannot know is the plate's true yield stress and thickness (they scatter around
the nominal values); the real bend - measure - compare loop corrects that.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import RectBivariateSpline
from scipy.optimize import minimize_scalar

from mppf.correct.compensate import compensate
from mppf.core.errors import InputError
from mppf.core.grid import tps_fill, without_plane
from mppf.forming.plate_model import grid_axes, loaded_surface, spring_back
from mppf.planning.press import PressConfig
from mppf.forming.material import Material

MODEL_SPACING_MM = 30.0
"""Grid spacing of the plate model used for the prediction."""

ITERATIONS = 10
"""Most virtual cycles."""

TOLERANCE_MM = 0.1
"""Virtual cycles stop when the predicted largest deviation at the punches is below this."""


@dataclass(frozen=True, eq=False)
class Refinement:
    """Strokes refined on the plate model.

    Attributes
    ----------
    upper_mm, lower_mm : (rows, cols) float
        Refined tip heights (NaN where inactive).
    predicted_max_mm : float
        Predicted largest deviation at the punches of the returned strokes, mm.
    history_mm : list of float
        Predicted largest deviation at the punches of each virtual cycle's strokes, mm.
    notes : list of str
    """

    upper_mm: np.ndarray
    lower_mm: np.ndarray
    predicted_max_mm: float
    history_mm: list[float] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def predict_mid_heights(press: PressConfig, upper_mm, lower_mm, active, outline_xy_mm, thickness_mm: float,
                        material: Material, spacing_mm: float = MODEL_SPACING_MM) -> np.ndarray:
    """Mid-surface heights at the punch axes after springback, by the plate model.

    Parameters
    ----------
    press : PressConfig
    upper_mm, lower_mm : (rows, cols) float
        Tip heights (NaN where inactive).
    active : (rows, cols) bool
    outline_xy_mm : (k, 2) float
        The plate's outline in press x, y.
    thickness_mm : float
    material : Material
    spacing_mm : float
        Grid spacing of the model.

    Returns
    -------
    (rows, cols) float
        Predicted heights, mm (all punches, inactive ones included).
    """
    px, py = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    xy = np.column_stack([px[active], py[active]])
    mid = 0.5 * (np.asarray(upper_mm, dtype=float) + np.asarray(lower_mm, dtype=float))[active]
    x_mm, y_mm = grid_axes(outline_xy_mm, spacing_mm)
    loaded = loaded_surface(xy, mid, x_mm, y_mm)
    unloaded, _ = spring_back(x_mm, y_mm, loaded, thickness_mm, material, outline_xy_mm)
    spline = RectBivariateSpline(y_mm, x_mm, unloaded, kx=3, ky=3, s=0)
    return spline.ev(py, px)


def _deviation(press: PressConfig, predicted, target, act) -> np.ndarray:
    """Predicted minus target at the active punches, its best plane removed (NaN elsewhere)."""
    px, py = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    return np.where(act, without_plane(px, py, predicted - target, act), np.nan)


def refine_strokes(press: PressConfig, upper_mm, lower_mm, active, target_mid_mm, outline_xy_mm,
                   thickness_mm: float, material: Material, *, iterations: int = ITERATIONS,
                   tolerance_mm: float = TOLERANCE_MM) -> Refinement:
    """Correct strokes on the plate model until the predicted plate matches the design.

    Parameters
    ----------
    press : PressConfig
    upper_mm, lower_mm : (rows, cols) float
        Starting tip heights (e.g. the over-bent plan), NaN where inactive.
    active : (rows, cols) bool
    target_mid_mm : (rows, cols) float
        The design's mid-surface height at each active punch axis (press z), in the
        same pose as the strokes.
    outline_xy_mm : (k, 2) float
        The plate's outline on the press (with its trim margin, if any).
    thickness_mm : float
    material : Material
        The NOMINAL material.
    iterations : int
        Most virtual cycles (>= 0).
    tolerance_mm : float
        Stop when the predicted largest deviation at the punches is below this.

    Returns
    -------
    Refinement
        The best strokes seen (the smallest predicted largest deviation).

    Raises
    ------
    InputError
        A negative iteration count or a non-positive tolerance.
    """
    if iterations < 0 or not tolerance_mm > 0:
        raise InputError(f"refinement needs iterations >= 0 and a positive tolerance, got {iterations}, "
                         f"{tolerance_mm} mm")
    act = np.asarray(active, dtype=bool)
    upper = np.where(act, np.asarray(upper_mm, dtype=float), np.nan)
    lower = np.where(act, np.asarray(lower_mm, dtype=float), np.nan)
    target = np.asarray(target_mid_mm, dtype=float)
    best = (np.inf, upper, lower)
    history: list[float] = []
    notes: list[str] = []
    for _ in range(iterations + 1):
        predicted = predict_mid_heights(press, upper, lower, act, outline_xy_mm, thickness_mm, material)
        # the deviation up to a rigid placement: the comparison of a scan removes its best plane
        error = _deviation(press, predicted, target, act)
        worst = float(np.max(np.abs(error[act])))
        history.append(worst)
        if worst < best[0]:
            best = (worst, upper, lower)
        if worst < tolerance_mm or len(history) > iterations:
            break
        step = compensate(upper, lower, error, press=press, thickness_mm=thickness_mm, material=material,
                          max_step_ratio=None)
        upper, lower = np.where(act, step.upper_mm, np.nan), np.where(act, step.lower_mm, np.nan)
    notes.append(f"{len(history) - 1} virtual cycle(s) on the plate model (nominal material): predicted "
                 f"largest deviation at the punches {history[0]:.2f} -> {best[0]:.2f} mm")
    return Refinement(upper_mm=best[1], lower_mm=best[2], predicted_max_mm=best[0], history_mm=history,
                      notes=notes)


YIELD_BOUNDS = (0.6, 1.6)
"""Range of the fitted effective yield stress, as factors of the nominal one."""

RESIDUAL_SMOOTHING = 10.0
"""Smoothing of the thin-plate spline through the measured residual (mm^2 units of the spline)."""

MIN_EXPLAINED = 0.25
"""The loop uses the calibrated correction only when the fitted model explains at least this share
of the measured deviations (:attr:`MaterialFit.explained`); else the model step of
:func:`mppf.correct.compensate.compensate`. Near tolerance the scan's noise and registration leave a
good model about half of a 1 mm RMS unexplained; a model that explains less than a quarter is
not trusted to solve the next strokes."""


@dataclass(frozen=True)
class MaterialFit:
    """The plate's effective material, fitted to measured cycles through the plate model.

    Attributes
    ----------
    material : Material
        The nominal material with the fitted yield stress.
    cost_nominal_mm2, cost_fit_mm2 : float
        Sum of squared differences (mm^2) between the measured and the predicted punch
        deviations over all cycles, with the nominal and with the fitted yield stress.
    n_cycles : int
    measured_mm2 : float
        Sum of the squared measured deviations (each cycle's mean removed), mm^2.
    """

    material: Material
    cost_nominal_mm2: float
    cost_fit_mm2: float
    n_cycles: int
    measured_mm2: float = float("nan")

    @property
    def explained(self) -> float:
        """Share of the measured deviations' squares (means removed) the fitted model explains."""
        return 1.0 - self.cost_fit_mm2 / self.measured_mm2 if self.measured_mm2 > 0 else 0.0


def fit_yield_stress(press: PressConfig, cycles, active, target_mid_mm, outline_xy_mm, thickness_mm: float,
                     nominal: Material) -> MaterialFit:
    """The yield stress that makes the plate model best predict the measured deviations.

    Springback depends on the material through ``c = sy' / (E' t)`` alone, so one number,
    the effective yield stress at the nominal thickness, carries both the yield stress's
    and the thickness's scatter. It is fitted (bounded scalar minimisation within
    ``YIELD_BOUNDS`` of the nominal) to the punch deviations measured after every cycle so
    far, each predicted from that cycle's strokes by :func:`predict_mid_heights`; each
    cycle's difference has its mean removed (the plate's height is not measured).

    Parameters
    ----------
    press : PressConfig
    cycles : sequence of (upper_mm, lower_mm, punch_error_mm)
        Each pressed cycle: tip heights (rows, cols; NaN where inactive) and the measured
        deviation at the punches (NaN where unknown), plane removed.
    active : (rows, cols) bool
    target_mid_mm : (rows, cols) float
        The design's mid-surface height at the punch axes (``Job.layout.design_mid_mm``).
    outline_xy_mm : (k, 2) float
        The plate as cut, on the press.
    thickness_mm : float
        Nominal thickness.
    nominal : Material

    Returns
    -------
    MaterialFit
    """
    act = np.asarray(active, dtype=bool)
    target = np.asarray(target_mid_mm, dtype=float)
    cycles = [(np.asarray(u, dtype=float), np.asarray(lo, dtype=float), np.asarray(e, dtype=float))
              for u, lo, e in cycles]

    def cost(yield_mpa: float) -> float:
        material = Material(nominal.youngs_modulus_mpa, nominal.poisson, float(yield_mpa))
        total = 0.0
        for upper, lower, error in cycles:
            predicted = _deviation(press, predict_mid_heights(press, upper, lower, act, outline_xy_mm, thickness_mm,
                                                              material), target, act)
            known = act & np.isfinite(error)
            diff = (predicted - error)[known]
            total += float(np.sum((diff - diff.mean()) ** 2)) if diff.size else 0.0
        return total

    lo, hi = (f * nominal.yield_stress_mpa for f in YIELD_BOUNDS)
    best = minimize_scalar(cost, bounds=(lo, hi), method="bounded", options={"xatol": 0.5})
    fitted = Material(nominal.youngs_modulus_mpa, nominal.poisson, float(best.x))
    measured = 0.0
    for _, _, error in cycles:
        values = error[act & np.isfinite(error)]
        measured += float(np.sum((values - values.mean()) ** 2)) if values.size else 0.0
    return MaterialFit(fitted, cost(nominal.yield_stress_mpa), float(best.fun), len(cycles), measured)


def calibrated_correction(press: PressConfig, cycles, active, target_mid_mm, outline_xy_mm, thickness_mm: float,
                          nominal: Material, *, iterations: int = ITERATIONS) -> tuple[Refinement, MaterialFit]:
    """Next strokes from the plate model calibrated on the measured cycles (model-based ILC).

    1. The effective yield stress is fitted to all cycles so far (:func:`fit_yield_stress`).
    2. The residual ``r`` the calibrated model does not explain (measured minus predicted
       deviation of the last cycle: model-form error, measurement error) is spread over
       the punch grid by a smoothing thin-plate spline.
    3. The strokes are refined on the calibrated model (:func:`refine_strokes`, from the
       last cycle's strokes) towards the design moved by ``-r``: so that the plate, which
       lands ``r`` off what the model predicts, lands on the design.

    Parameters
    ----------
    cycles : sequence of (upper_mm, lower_mm, punch_error_mm)
        Every pressed cycle, the last one last (see :func:`fit_yield_stress`).
    Other parameters as :func:`fit_yield_stress`; ``iterations`` as :func:`refine_strokes`.

    Returns
    -------
    refinement : Refinement
        The new strokes (NaN where inactive) and the predicted deviation against the
        residual-corrected target.
    fit : MaterialFit

    Raises
    ------
    InputError
        No cycle given, or too few measured punches (fewer than 6) in the last one.
    """
    if not cycles:
        raise InputError("the calibrated correction needs at least one measured cycle")
    act = np.asarray(active, dtype=bool)
    target = np.asarray(target_mid_mm, dtype=float)
    fit = fit_yield_stress(press, cycles, act, target, outline_xy_mm, thickness_mm, nominal)
    upper, lower, error = (np.asarray(a, dtype=float) for a in cycles[-1])
    known = act & np.isfinite(error)
    if known.sum() < 6:
        raise InputError(f"only {int(known.sum())} punches have a measured deviation; the calibrated "
                         "correction needs at least 6")
    predicted = _deviation(press, predict_mid_heights(press, upper, lower, act, outline_xy_mm, thickness_mm,
                                                      fit.material), target, act)
    px, py = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    spread = np.full(press.shape, np.nan)
    spread[act] = tps_fill(np.column_stack([px[known], py[known]]), (error - predicted)[known],
                           np.column_stack([px[act], py[act]]), smoothing=RESIDUAL_SMOOTHING)
    refinement = refine_strokes(press, upper, lower, act, target - spread, outline_xy_mm, thickness_mm, fit.material,
                                iterations=iterations)
    notes = [f"plate model calibrated on {fit.n_cycles} cycle(s): effective yield stress "
             f"{fit.material.yield_stress_mpa:.0f} MPa (nominal {nominal.yield_stress_mpa:.0f}); squared misfit "
             f"{fit.cost_nominal_mm2:.0f} -> {fit.cost_fit_mm2:.0f} mm^2, {100 * fit.explained:.0f} % of the "
             f"measured deviations explained; residual the model does not explain "
             f"up to {np.nanmax(np.abs(spread)):.2f} mm", *refinement.notes]
    return Refinement(refinement.upper_mm, refinement.lower_mm, refinement.predicted_max_mm, refinement.history_mm,
                      notes), fit
