"""The springback-model step: the measured error undone through the slope of the springback law.

The step of the planner's virtual press cycles (:func:`mppf.correct.compensate.compensate`): with the
plate's nominal material the change is computed through the springback law instead of ``-lambda e``:
each curvature component of the error is divided by the slope of the springback map at the loaded
curvature, so a twist error, which springs back much more than a bend, gets a larger step. See ``docs/compare.md``,
section "The springback-model step".
"""

from __future__ import annotations

import numpy as np

from mppf.core.grid import hessian, integrate_hessian, principal, tensor, tps_fill, without_plane
from mppf.correct.result import Step, punch_grid
from mppf.forming.springback import unloaded_curvature
from mppf.model.material import Material
from mppf.model.press import PressConfig

MIN_SLOPE = 0.2
"""Smallest springback slope the model-based correction divides by (at most 5 x the error:
a damping against the scan noise, which the division would amplify as much)."""

MAX_STEP_RATIO = 2.5
"""Trust region of the model-based correction: no punch moves by more than this times the
plate's largest measured error (the whole step is scaled down when one would)."""

FILL_SMOOTHING = 1.0
"""Smoothing of the thin-plate spline that fills the error grid where no punch has data."""


def model_step(upper_mm, lower_mm, punch_error_mm, *, press: PressConfig, thickness_mm: float, material: Material,
               gain: float, max_step_ratio: float | None) -> Step:
    """``gain`` times the springback-model correction (:func:`model_correction`), in its trust region.

    Parameters
    ----------
    upper_mm, lower_mm : (rows, cols) float
        Tip heights pressed (NaN where inactive).
    punch_error_mm : (rows, cols) float
        Measured deviation at the punches, positive = plate above the design (NaN: unknown).
    press : PressConfig
    thickness_mm : float
    material : Material
        The plate's nominal material.
    gain : float
        Factor on the model's correction.
    max_step_ratio : float or None
        The step is scaled down as a whole when a punch would move by more than this
        times the largest measured error; None = no limit (the planner's virtual cycles,
        where the model is its own truth).

    Returns
    -------
    Step
        Acting where the punch is active and its error known or the model moves it.
    """
    upper = np.asarray(upper_mm, dtype=float)
    lower = np.asarray(lower_mm, dtype=float)
    error = np.asarray(punch_error_mm, dtype=float)
    active = np.isfinite(upper) & np.isfinite(lower)
    model = model_correction(upper, lower, error, press=press, thickness_mm=thickness_mm, material=material)
    known = active & (np.isfinite(error) | (model != 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(known & np.isfinite(error) & (np.abs(error) > 0.5), -gain * model / error, np.nan)
    notes = [f"springback-model correction (nominal material, gain {gain:g}); effective gain median "
             f"{np.nanmedian(ratio) if np.isfinite(ratio).any() else gain:.2f} where |e| > 0.5 mm"]
    wanted = np.where(known, gain * model, 0.0)
    # trust region: the model is a linearisation; far from the design (a plate measured
    # after an interrupted job, a gross error) the step is scaled down as a whole
    cap = max_step_ratio * float(np.nanmax(np.abs(np.where(known, error, np.nan)))) \
        if max_step_ratio is not None and np.isfinite(error[known]).any() else 0.0
    largest = float(np.max(np.abs(wanted))) if wanted.size else 0.0
    if cap > 0 and largest > cap:
        wanted *= cap / largest
        notes.append(f"model step scaled by {cap / largest:.2f} (trust region: at most {max_step_ratio:g} x "
                     "the largest error)")
    return Step(wanted_mm=wanted, known=known, gain=np.where(active, gain, np.nan), notes=notes)


def springback_slopes(k1, k2, thickness_mm: float, material: Material):
    """Slopes of the springback map at loaded principal curvatures ``k1, k2`` (1/mm, any shape).

    ``f(k) = k R_i/R_f`` (:func:`mppf.forming.springback.unloaded_curvature`) maps a loaded principal
    curvature to the unloaded one. A small change of the loaded curvature tensor changes the
    unloaded one, in the principal axes of the loaded tensor, by

    - ``f'(k_i) = 1 - 8 c^3 / |k_i|^3`` along each principal direction (0 below the elastic
      limit ``2 c``, where the plate springs back flat), ``c = sy' / (E' t)``, and
    - ``(f(k1) - f(k2)) / (k1 - k2)`` for the twist (off-diagonal) part: a matrix function's
      divided difference; about the springback ratio ``R_i/R_f`` for a cylinder, much less
      than 1 for a saddle.

    Returns
    -------
    d1, d2, twist : float arrays like ``k1``
    """
    k1 = np.asarray(k1, dtype=float)
    k2 = np.asarray(k2, dtype=float)
    c = material.plane_strain_yield_mpa / (material.plane_strain_modulus_mpa * thickness_mm)

    def slope(k):
        mag = np.maximum(np.abs(k), c)  # below 2 c the slope is 0 anyway
        return np.where(mag >= 2.0 * c, 1.0 - 8.0 * c**3 / mag**3, 0.0)

    f1 = unloaded_curvature(k1, thickness_mm, material)
    f2 = unloaded_curvature(k2, thickness_mm, material)
    close = np.abs(k1 - k2) < 1e-9
    with np.errstate(invalid="ignore", divide="ignore"):
        twist = np.where(close, slope(0.5 * (k1 + k2)), (f1 - f2) / np.where(close, 1.0, k1 - k2))
    return slope(k1), slope(k2), twist


def model_correction(upper_mm, lower_mm, punch_error_mm, *, press: PressConfig, thickness_mm: float,
                     material: Material) -> np.ndarray:
    """Stroke correction (rows, cols) that undoes the measured error through the springback model.

    A quasi-Newton step with the model's slope instead of secants from noisy data:

    1. the loaded mid-surface ``(upper + lower) / 2`` and the measured error ``e`` on the
       punch grid (thin-plate splines fill the punches without data);
    2. their curvature tensors (second differences on the punch grid): the loaded ``K_i``
       and the wanted change of the unloaded one, ``dK_f = -Hess(e)``;
    3. in the principal axes of ``K_i`` each component of ``dK_f`` is divided by its
       springback slope (:func:`springback_slopes`, nominal material, at least
       ``MIN_SLOPE``): ``dK_i``;
    4. ``dK_i`` is integrated back to heights (least squares), its best plane over the
       active punches removed (the comparison fixes the plate's rigid position).

    Where the slopes are 1 (sharp bends) this is the plain displacement adjustment
    ``-e``; where the plate springs back more (near the elastic limit, the twist of a
    saddle) the step is larger, as the model says it must be.

    Returns
    -------
    (rows, cols) float
        Correction to add to both matrices (0 where inactive).

    Raises
    ------
    InputError
        Grids of another shape than the press's.
    """
    upper, lower, error = (punch_grid(press, a, name) for a, name in
                           ((upper_mm, "upper_mm"), (lower_mm, "lower_mm"), (punch_error_mm, "punch_error_mm")))
    active = np.isfinite(upper) & np.isfinite(lower)
    known = active & np.isfinite(error)
    if known.sum() < 6:
        return np.where(known, -np.where(known, error, 0.0), 0.0)
    px, py = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    grid_xy = np.column_stack([px.ravel(), py.ravel()])
    mid = _filled(grid_xy, active, 0.5 * (upper + lower), 0.0)
    err = _filled(grid_xy, known, error, FILL_SMOOTHING)
    hx, hy = press.pitch_x_mm, press.pitch_y_mm
    kappa, vec = principal(*hessian(mid, hx, hy))
    exx, exy, eyy = hessian(err, hx, hy)
    d1, d2, twist = (np.maximum(s, MIN_SLOPE) for s in springback_slopes(kappa[..., 0], kappa[..., 1],
                                                                         thickness_mm, material))
    want = -tensor(exx, exy, eyy)
    local = np.einsum("...ki,...kl,...lj->...ij", vec, want, vec)  # in the loaded principal axes
    scale = tensor(d1, twist, d2)
    loaded = np.einsum("...ik,...kl,...jl->...ij", vec, local / scale, vec)
    dz = integrate_hessian(loaded[..., 0, 0], loaded[..., 0, 1], loaded[..., 1, 1], hx, hy)
    return np.where(active, without_plane(px, py, dz, active), 0.0)


def _filled(grid_xy: np.ndarray, mask: np.ndarray, values: np.ndarray, smoothing: float) -> np.ndarray:
    """``values`` on the whole punch grid: a thin-plate spline through the entries in ``mask``."""
    return tps_fill(grid_xy[mask.ravel()], values[mask], grid_xy, smoothing=smoothing).reshape(mask.shape)
