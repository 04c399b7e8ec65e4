"""The calibrated correction: the plate model fitted to the measured cycles, the next strokes solved on it.

Springback depends on the material through ``c = sy' / (E' t)`` alone, so one number, the
plate's effective yield stress at the nominal thickness, carries both the yield stress's and
the thickness's scatter. :func:`fit_yield_stress` finds it from every cycle measured so far
(the plate model of :mod:`mppf.forming.plate_model`, predicted by
:func:`mppf.forming.precompensate.predict_mid_heights`); :func:`calibrated_correction` then
refines the strokes on the calibrated model past the residual it does not explain
(model-based iterative learning control); :func:`calibrated_step` is the loop's use of it,
held to the press's limits, or None when the fit explains too little.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.errors import GeometryError, InputError
from mppf.core.grid import tps_fill
from mppf.correct.limits import limit_correction, limited_notes
from mppf.correct.result import Correction
from mppf.correct.virtual_cycles import ITERATIONS, Refinement, refine_strokes
from mppf.forming.precompensate import deviation, predict_mid_heights
from mppf.model.job_parts import PlateLayout, StepStrokes
from mppf.model.material import Material
from mppf.model.press import PressConfig

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

MIN_MEASURED_PUNCHES = 6
"""Fewest punches with a measured deviation in the last cycle the calibrated correction needs."""


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

    Fitted (bounded scalar minimisation within ``YIELD_BOUNDS`` of the nominal) to the punch
    deviations measured after every cycle so far, each predicted from that cycle's strokes
    by :func:`mppf.forming.precompensate.predict_mid_heights`; each cycle's difference has
    its mean removed (the plate's height is not measured).

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
    from scipy.optimize import minimize_scalar

    act = np.asarray(active, dtype=bool)
    target = np.asarray(target_mid_mm, dtype=float)
    cycles = [(np.asarray(u, dtype=float), np.asarray(lo, dtype=float), np.asarray(e, dtype=float))
              for u, lo, e in cycles]

    def cost(yield_mpa: float) -> float:
        material = Material(nominal.youngs_modulus_mpa, nominal.poisson, float(yield_mpa))
        total = 0.0
        for upper, lower, error in cycles:
            predicted = deviation(press, predict_mid_heights(press, upper, lower, act, outline_xy_mm, thickness_mm,
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
    # 1. enough data: a cycle, and enough measured punches in the last one
    if not cycles:
        raise InputError("the calibrated correction needs at least one measured cycle")
    act = np.asarray(active, dtype=bool)
    target = np.asarray(target_mid_mm, dtype=float)
    upper, lower, error = (np.asarray(a, dtype=float) for a in cycles[-1])
    known = act & np.isfinite(error)
    if known.sum() < MIN_MEASURED_PUNCHES:
        raise InputError(f"only {int(known.sum())} punches have a measured deviation; the calibrated "
                         f"correction needs at least {MIN_MEASURED_PUNCHES}")
    # 2. the effective yield stress from every cycle so far
    fit = fit_yield_stress(press, cycles, act, target, outline_xy_mm, thickness_mm, nominal)
    # 3. the residual the calibrated model does not explain, spread over the active punches
    predicted = deviation(press, predict_mid_heights(press, upper, lower, act, outline_xy_mm, thickness_mm,
                                                     fit.material), target, act)
    px, py = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    spread = np.full(press.shape, np.nan)
    spread[act] = tps_fill(np.column_stack([px[known], py[known]]), (error - predicted)[known],
                           np.column_stack([px[act], py[act]]), smoothing=RESIDUAL_SMOOTHING)
    # 4. the strokes refined on the calibrated model towards the design moved by the residual
    refinement = refine_strokes(press, StepStrokes(upper, lower, act), target - spread, outline_xy_mm, thickness_mm,
                                fit.material, iterations=iterations)
    notes = [f"plate model calibrated on {fit.n_cycles} cycle(s): effective yield stress "
             f"{fit.material.yield_stress_mpa:.0f} MPa (nominal {nominal.yield_stress_mpa:.0f}); squared misfit "
             f"{fit.cost_nominal_mm2:.0f} -> {fit.cost_fit_mm2:.0f} mm^2, {100 * fit.explained:.0f} % of the "
             f"measured deviations explained; residual the model does not explain "
             f"up to {np.nanmax(np.abs(spread)):.2f} mm", *refinement.notes]
    return Refinement(refinement.upper_mm, refinement.lower_mm, refinement.predicted_max_mm, refinement.history_mm,
                      notes), fit


def calibrated_step(press: PressConfig, cycles, step: StepStrokes, layout: PlateLayout, thickness_mm: float,
                    nominal: Material) -> Correction | None:
    """The loop's calibrated correction of the step just pressed, held to the press's limits; or None.

    Parameters
    ----------
    press : PressConfig
    cycles : sequence of (upper_mm, lower_mm, punch_deviation_mm)
        (rows, cols) arrays of every measured cycle so far, the one just measured last.
    step : StepStrokes
        The strokes just pressed (the last step of the last cycle).
    layout : PlateLayout
        The job's plate layout: the plate as cut and the design's heights at the punches.
    thickness_mm : float
    nominal : Material
        The plate's nominal material.

    Returns
    -------
    Correction or None
        None (the loop then takes the model step of :func:`mppf.correct.compensate.compensate`)
        when the layout has no design heights at the punches, the data do not allow the
        calibration (InputError, GeometryError), or the fitted model explains less than
        ``MIN_EXPLAINED`` of the measured deviations.
    """
    if layout is None or layout.design_mid_mm is None:
        return None
    active = np.asarray(step.active, dtype=bool)
    try:
        refined, fit = calibrated_correction(press, cycles, active, layout.design_mid_mm, layout.outline_mm,
                                             thickness_mm, nominal)
    except (InputError, GeometryError):
        return None
    if fit.explained < MIN_EXPLAINED:
        return None
    # the change from the strokes just pressed, held to the dimpling and stroke limits
    upper = np.where(active, step.upper_mm, np.nan)
    lower = np.where(active, step.lower_mm, np.nan)
    applied, clipped = limit_correction(press, upper, lower, refined.lower_mm - step.lower_mm)
    return Correction(upper_mm=np.where(active, step.upper_mm + applied, np.nan),
                      lower_mm=np.where(active, step.lower_mm + applied, np.nan), gain=np.where(active, 1.0, np.nan),
                      applied_mm=applied, clipped=clipped, notes=[*refined.notes, *limited_notes(press, clipped)])
