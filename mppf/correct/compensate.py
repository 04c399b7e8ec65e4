"""Stroke compensation: displacement adjustment with a secant gain per punch.

After a press cycle the plate is scanned and compared; ``e`` is the plate's deviation
from the design at each punch, measured along the stroke direction (press z):
``e > 0`` means the formed plate lies ABOVE the design there. The next strokes are

    h_next = h - lambda * e          (displacement adjustment, DA)

applied to both matrices alike (upper and lower tips move by the same amount, so the
gap stays the plate thickness). ``lambda`` is the inverse of the stroke-to-shape gain
``de/dh``. From the second cycle on it is estimated per punch by the secant of the last
two cycles (the "modified DA"),

    lambda_ij = (h_k - h_{k-1}) / (e_k - e_{k-1}),

clipped to [0.5, 3] and averaged half and half with the plate-wide least-squares secant
(the plate couples neighbouring punches, which makes a punch's own secant noisy). Where a
punch's own secant is unreliable (a stroke or deviation change below 0.1 mm, or a negative
estimate) the plate-wide one is used, and the default gain where that fails too. The
corrections are smoothed on the punch grid, then limited so that neighbouring
corrections differ by at most the press's dimpling limit (``max_neighbour_diff_mm``)
and every corrected stroke stays within the matrices' tip-height limits.

With the plate's nominal material (``material=``, the loop's default) the step is instead
computed through the springback law (:func:`model_correction`): each curvature component of
the error is divided by the slope of the springback map at the loaded curvature, so a twist
error, which springs back much more than a bend, gets a larger step. See
``docs/compare.md``, section "The springback-model step and the secant gains".
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from mppf.core.errors import InputError
from mppf.core.grid import (hessian, integrate_hessian, largest_neighbour_difference, neighbour_mean, principal, tensor,
                            tps_fill, without_plane)
from mppf.planning.press import PressConfig
from mppf.forming.material import Material
from mppf.forming.springback import unloaded_curvature

GAIN_RANGE = (0.5, 3.0)
"""Range the secant gain is clipped to."""

SECANT_MIN_MM = 0.1
"""Smallest stroke change and deviation change between cycles that gives a secant gain."""

SECANT_BLEND = 0.5
"""Weight of a punch's own secant gain against the plate-wide secant gain."""

SMOOTHING = 0.25
"""Weight of the neighbour average in the smoothed correction (0 = none, 1 = only neighbours)."""

MIN_SLOPE = 0.2
"""Smallest springback slope the model-based correction divides by (at most 5 x the error:
a damping against the scan noise, which the division would amplify as much)."""

MAX_STEP_RATIO = 2.5
"""Trust region of the model-based correction: no punch moves by more than this times the
plate's largest measured error (the whole step is scaled down when one would)."""

FILL_SMOOTHING = 1.0
"""Smoothing of the thin-plate spline that fills the error grid where no punch has data."""


@dataclass(frozen=True)
class PreviousCycle:
    """What the secant gain needs from the last cycle.

    Attributes
    ----------
    lower_mm : (rows, cols) float
        Lower tip heights pressed in the last cycle (the upper ones moved alike).
    punch_error_mm : (rows, cols) float
        The deviation measured after the last cycle (NaN where unknown).
    """

    lower_mm: np.ndarray
    punch_error_mm: np.ndarray


@dataclass(frozen=True, eq=False)
class Correction:
    """Corrected strokes for the next cycle.

    Attributes
    ----------
    upper_mm, lower_mm : (rows, cols) float
        Corrected tip heights (NaN where the punch is inactive).
    gain : (rows, cols) float
        lambda used per punch (NaN where inactive).
    applied_mm : (rows, cols) float
        Correction added to both matrices (0 where inactive or no error known).
    clipped : (rows, cols) bool
        Where the dimpling or stroke limit reduced the correction.
    notes : list of str
        What happened, for the operator and the history.
    """

    upper_mm: np.ndarray
    lower_mm: np.ndarray
    gain: np.ndarray
    applied_mm: np.ndarray
    clipped: np.ndarray
    notes: list[str] = field(default_factory=list)


def compensate(
    upper_mm,
    lower_mm,
    punch_error_mm,
    *,
    press: PressConfig,
    thickness_mm: float,
    gain: float = 1.0,
    previous: PreviousCycle | Mapping | None = None,
    smoothing: float = SMOOTHING,
    material: Material | None = None,
    max_step_ratio: float | None = MAX_STEP_RATIO,
) -> Correction:
    """Correct the strokes of one press step from the measured deviation at the punches.

    Parameters
    ----------
    upper_mm, lower_mm : (rows, cols) float
        Tip heights pressed in the cycle just measured (NaN where inactive).
    punch_error_mm : (rows, cols) float
        Deviation of the formed plate from the design at each punch along press z
        (``Comparison.punch_deviation_mm``): positive = plate above the design. NaN
        where unknown (no correction there).
    press : PressConfig
    thickness_mm : float
        Plate thickness; a note is added where the gap ``upper - lower`` differs from it.
    gain : float
        Default lambda (the first cycle, and where the secant is unreliable).
    previous : PreviousCycle or mapping with ``lower_mm`` and ``punch_error_mm``, optional
        The cycle before, for the secant gain.
    smoothing : float
        Weight of the neighbour average in the correction, in [0, 1].
    material : Material, optional
        Nominal plate material: correct through the springback model
        (:func:`model_correction`, times ``gain``) instead of ``-lambda e``; ``previous``
        is then not used (the model gives the slope, no secant from noisy data).
    max_step_ratio : float or None
        Trust region of the model step: scaled down as a whole when a punch would move
        by more than this times the largest measured error; None = no limit (the virtual
        cycles of :mod:`mppf.forming.precompensate`, where the model is its own truth).

    Returns
    -------
    Correction

    Raises
    ------
    InputError
        Wrong shapes, a non-positive gain or a smoothing weight outside [0, 1].
    """
    upper, lower, error = (_grid(press, a, name) for a, name in
                           ((upper_mm, "upper_mm"), (lower_mm, "lower_mm"), (punch_error_mm, "punch_error_mm")))
    if not (np.isfinite(gain) and gain > 0):
        raise InputError(f"the default gain must be positive, got {gain}", hint="1.0 is a safe start")
    if not 0.0 <= smoothing <= 1.0:
        raise InputError(f"smoothing must be within 0..1, got {smoothing}")
    active = np.isfinite(upper) & np.isfinite(lower)
    known = active & np.isfinite(error)
    notes: list[str] = []
    gap = (upper - lower)[active]
    if gap.size and np.max(np.abs(gap - thickness_mm)) > 0.5:
        notes.append(f"gap upper - lower differs from the thickness {thickness_mm:g} mm by up to "
                     f"{np.max(np.abs(gap - thickness_mm)):.2f} mm")

    # 1. gain per punch: the secant of the last two cycles, else the default
    lam = np.where(active, float(gain), np.nan)
    if material is not None:
        model = model_correction(upper, lower, error, press=press, thickness_mm=thickness_mm, material=material)
        known = active & (np.isfinite(error) | (model != 0.0))
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = np.where(known & np.isfinite(error) & (np.abs(error) > 0.5), -gain * model / error, np.nan)
        notes.append(f"springback-model correction (nominal material, gain {gain:g}); effective gain median "
                     f"{np.nanmedian(ratio) if np.isfinite(ratio).any() else gain:.2f} where |e| > 0.5 mm")
        raw = np.where(known, gain * model, 0.0)
        # trust region: the model is a linearisation; far from the design (a plate measured
        # after an interrupted job, a gross error) the step is scaled down as a whole
        cap = max_step_ratio * float(np.nanmax(np.abs(np.where(known, error, np.nan)))) \
            if max_step_ratio is not None and np.isfinite(error[known]).any() else 0.0
        largest = float(np.max(np.abs(raw))) if raw.size else 0.0
        if cap > 0 and largest > cap:
            raw *= cap / largest
            notes.append(f"model step scaled by {cap / largest:.2f} (trust region: at most {max_step_ratio:g} x "
                         "the largest error)")
    elif previous is not None:
        lam, fallback = _secant_gain(press, lower, error, previous, float(gain), known)
        lam = np.where(active, lam, np.nan)
        notes.append(f"own secant gain at {int((known & ~fallback).sum())} punches, plate-wide or default at "
                     f"{int((known & fallback).sum())}; gain range {np.nanmin(lam[known]) if known.any() else gain:.2f}"
                     f"..{np.nanmax(lam[known]) if known.any() else gain:.2f}")

    # 2. raw displacement adjustment, smoothed on the punch grid
    if material is None:
        raw = np.where(known, -lam * np.where(known, error, 0.0), 0.0)
    smooth = (1.0 - smoothing) * raw + smoothing * neighbour_mean(raw, known)
    smooth = np.where(known, smooth, 0.0)

    # 3. limits: dimpling (neighbour differences of the correction) and tip heights
    applied, clipped = limit_correction(press, upper, lower, smooth)
    if clipped.any():
        notes.append(f"correction limited at {int(clipped.sum())} punches (dimpling limit "
                     f"{press.max_neighbour_diff_mm:g} mm or stroke limits)")
    return Correction(
        upper_mm=np.where(active, upper + applied, np.nan),
        lower_mm=np.where(active, lower + applied, np.nan),
        gain=lam,
        applied_mm=np.where(active, applied, 0.0),
        clipped=clipped,
        notes=notes,
    )


def limit_correction(press: PressConfig, upper_mm, lower_mm, correction_mm) -> tuple[np.ndarray, np.ndarray]:
    """A correction of both matrices held to the press's limits.

    Neighbouring corrections differ by at most the dimpling limit
    (``press.max_neighbour_diff_mm``) and every corrected tip stays within its matrix's
    height limits (alternating projections, :func:`_limit`).

    Parameters
    ----------
    press : PressConfig
    upper_mm, lower_mm : (rows, cols) float
        Tip heights before the correction (NaN where inactive).
    correction_mm : (rows, cols) float
        Wanted change of both matrices (mm).

    Returns
    -------
    applied_mm : (rows, cols) float
        The correction applied (0 where inactive).
    clipped : (rows, cols) bool
        Where the limits reduced it.
    """
    upper = np.asarray(upper_mm, dtype=float)
    lower = np.asarray(lower_mm, dtype=float)
    active = np.isfinite(upper) & np.isfinite(lower)
    wanted = np.where(active, np.asarray(correction_mm, dtype=float), 0.0)
    lo = np.maximum(press.upper.min_mm - upper, press.lower.min_mm - lower)
    hi = np.minimum(press.upper.max_mm - upper, press.lower.max_mm - lower)
    applied = _limit(wanted, active, lo, hi, press.max_neighbour_diff_mm)
    return np.where(active, applied, 0.0), active & (np.abs(applied - wanted) > 1e-9)


def _grid(press: PressConfig, values, name: str) -> np.ndarray:
    arr = np.asarray(values, dtype=float)
    if arr.shape != press.shape:
        raise InputError(f"{name} has shape {arr.shape}, the press has {press.shape}")
    return arr


def _secant_gain(press, lower, error, previous, default: float, known) -> tuple[np.ndarray, np.ndarray]:
    """Per-punch secant gain, blended with the plate-wide one; and where the punch's own fell back.

    The per-punch secant ``dh / de`` is noisy where neighbouring punches changed too (the
    plate couples them), so it is averaged half and half with the plate-wide least-squares
    secant ``sum(dh de) / sum(de^2)``. Punches without a usable secant of their own take the
    plate-wide one (or the default when that is unusable too).
    """
    if isinstance(previous, Mapping):
        try:
            previous = PreviousCycle(lower_mm=previous["lower_mm"], punch_error_mm=previous["punch_error_mm"])
        except KeyError as exc:
            raise InputError(f"previous cycle lacks {exc}", hint="give lower_mm and punch_error_mm") from None
    lower_prev = _grid(press, previous.lower_mm, "previous lower_mm")
    error_prev = _grid(press, previous.punch_error_mm, "previous punch_error_mm")
    dh = lower - lower_prev
    de = error - error_prev
    with np.errstate(invalid="ignore", divide="ignore"):
        secant = dh / de
    ok = known & np.isfinite(secant) & (np.abs(dh) >= SECANT_MIN_MM) & (np.abs(de) >= SECANT_MIN_MM) & (secant > 0)
    plate_wide = default
    if ok.sum() >= 3:
        estimate = float(np.sum(dh[ok] * de[ok]) / np.sum(de[ok] ** 2))
        if estimate > 0:
            plate_wide = float(np.clip(estimate, *GAIN_RANGE))
    own = np.clip(np.where(ok, secant, default), *GAIN_RANGE)
    lam = np.where(ok, SECANT_BLEND * own + (1.0 - SECANT_BLEND) * plate_wide, plate_wide)
    return lam, ~ok


def _limit(correction, active, lo, hi, max_diff_mm: float, iterations: int = 200) -> np.ndarray:
    """Clip ``correction`` to [lo, hi] and to neighbour differences <= ``max_diff_mm``.

    Alternating projections: each violating neighbour pair is pulled towards its mean,
    then the stroke range is enforced; a final uniform scale-down guarantees both.
    """
    c = np.clip(np.where(active, correction, 0.0), np.where(active, lo, 0.0), np.where(active, hi, 0.0))
    for _ in range(iterations):
        changed = False
        for axis in (0, 1):
            a = np.moveaxis(c, axis, 0)
            act = np.moveaxis(active, axis, 0)
            pair = act[1:] & act[:-1]
            diff = a[1:] - a[:-1]
            excess = np.where(pair, np.abs(diff) - max_diff_mm, 0.0)
            if np.any(excess > 1e-9):
                changed = True
                shift = 0.5 * np.sign(diff) * np.maximum(excess, 0.0) * (1 + 1e-6)
                a[1:] -= shift  # views: modify c in place
                a[:-1] += shift
        c = np.clip(c, np.where(active, lo, 0.0), np.where(active, hi, 0.0))
        if not changed and largest_neighbour_difference(c, active) <= max_diff_mm + 1e-9:
            return c
    # rare: did not settle; shrink towards zero, which satisfies both limits when 0 does
    worst = largest_neighbour_difference(c, active)
    if worst > max_diff_mm:
        c = c * (max_diff_mm / worst)
    return c


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
    """
    upper, lower, error = (_grid(press, a, name) for a, name in
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
