"""The plate model's prediction for springback pre-compensation: the sprung-back plate at the punches.

The planner's first guess over-bends the design's principal arcs (:mod:`mppf.planning.overbend`).
That guess is uniform over the plate: it misses where the curvature varies (saddles,
flares) and the plate's edges, where the plate between the outer punches and the edge is
not held (:mod:`mppf.forming.plate_model`: the loaded plate is the least-bending surface through
the contact points). :func:`predict_mid_heights` predicts the sprung-back plate from the strokes and
:func:`deviation` measures it against the design at every punch as a scan's comparison would;
the virtual press cycles that correct the strokes on this prediction before anything is pressed
are :func:`mppf.correct.virtual_cycles.refine_strokes` (they use the correction's own step).
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import RectBivariateSpline

from mppf.core.grid import without_plane
from mppf.forming.plate_model import grid_axes, loaded_surface, spring_back
from mppf.model.material import Material
from mppf.model.press import PressConfig

MODEL_SPACING_MM = 30.0
"""Grid spacing of the plate model used for the prediction."""


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
