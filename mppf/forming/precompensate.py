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
the nominal values); the real bend - measure - compare loop corrects that, with the plate
model calibrated on the measured cycles (:mod:`mppf.correct.calibrated`, which uses this
module: the dependency runs one way, correct.calibrated -> forming.precompensate ->
correct.compensate).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import RectBivariateSpline

from mppf.core.grid import without_plane
from mppf.core.validate import check_number
from mppf.correct.compensate import compensate
from mppf.forming.material import Material
from mppf.forming.plate_model import grid_axes, loaded_surface, spring_back
from mppf.planning.press import PressConfig

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


def deviation(press: PressConfig, predicted, target, active) -> np.ndarray:
    """Predicted minus target heights at the active punches, their best plane removed.

    The deviation up to a rigid placement, as the comparison of a scan measures it.

    Parameters
    ----------
    press : PressConfig
    predicted, target : (rows, cols) float
        Mid-surface heights at the punch axes, mm.
    active : (rows, cols) bool

    Returns
    -------
    (rows, cols) float
        mm, NaN where inactive.
    """
    act = np.asarray(active, dtype=bool)
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
    iterations = check_number("the refinement's iterations", iterations, low=0, integer=True)
    tolerance_mm = check_number("the refinement's tolerance", tolerance_mm, low=0.0, low_open=True, unit="mm")
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
        error = deviation(press, predicted, target, act)
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
