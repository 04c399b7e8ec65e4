"""The plate's deviation at each punch of the press: measured near its axis, filled in across scan gaps."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from mppf.core.grid import tps_fill
from mppf.core.polygon import contains, convex_outline, offset_convex
from mppf.core.transform import apply_rotation, apply_tf

RADIUS_PITCHES = 0.45
"""Default radius around a punch axis whose points give its deviation, in punch pitches."""

MIN_POINTS = 3
"""Fewest measured points within the radius that measure a punch."""

SLOPE_FLOOR = 0.2
"""The design normal's press-z component is held at least this when a normal deviation is
turned into one along the stroke."""

FILL_SMOOTHING = 0.1
"""Smoothing of the thin-plate spline that fills the punches in scan gaps."""


def punch_deviations(punch_xy_mm, tf_press_design, skin, dev, use, design_points, radius_mm=None):
    """Deviation of the plate at each punch along press z and along the design normal.

    Parameters
    ----------
    punch_xy_mm : (rows, cols, 2) float, mm
        Punch axes in press coordinates.
    tf_press_design : (4, 4) float
        Design -> press.
    skin : mppf.measure.deviations.DesignSkin
    dev : mppf.measure.deviations.Deviation
        The scan's deviations at its final transform.
    use : (n,) bool
        The measured points that count (net and trim margin, not outside, not outliers).
    design_points : (m, 3) float, mm
        The design (its outline, grown by the margin, says which punches are on the plate).
    radius_mm : float, optional
        Radius around an axis whose points give its deviation (default: ``RADIUS_PITCHES``
        of the punch pitch).

    Returns
    -------
    along_z, along_normal : (rows, cols) float, mm
        Positive = plate above the design; NaN where the punch is off the plate.
    interpolated : (rows, cols) bool
        Punches without measured points nearby (occlusion) whose value is filled in.
    """
    press_local = np.asarray(tf_press_design, dtype=float) @ skin.frame.tf_world_local
    uv = dev.uv
    n_z = apply_rotation(press_local, skin.fitted.surface.normals(uv[:, 0], uv[:, 1]))[:, 2] * skin.sign
    foot_press = apply_tf(press_local, np.asarray(dev.feet.xyz, dtype=float))
    design_press = apply_tf(tf_press_design, design_points)
    return punch_values(np.asarray(punch_xy_mm, dtype=float), foot_press[use, :2], dev.deviation_mm[use],
                        np.maximum(n_z[use], SLOPE_FLOOR), design_press[:, :2], radius_mm, skin.margin_mm)


def punch_values(punch_xy, xy, deviation, n_z, design_xy, radius_mm, margin_mm: float = 0.0):
    """Median deviation near each punch axis; interpolated where the scan has a gap.

    Parameters
    ----------
    punch_xy : (rows, cols, 2) float, mm
        Punch axes in press coordinates.
    xy : (p, 2) float, mm
        Press (x, y) of the foot points of the measured points used (net and margin).
    deviation, n_z : (p,) float
        Their normal deviations (mm) and the press-z components of the design normal.
    design_xy : (m, 2) float, mm
        The design points' press (x, y).
    radius_mm : float or None
        Radius around an axis whose points give its deviation (None: ``RADIUS_PITCHES``
        of the punch pitch).
    margin_mm : float
        Trim margin: a punch is on the plate when its axis lies inside the convex outline
        of ``design_xy`` grown by it.

    Returns
    -------
    along_z, along_normal : (rows, cols) float
        NaN where the punch is off the plate.
    interpolated : (rows, cols) bool
    """
    rows, cols, _ = punch_xy.shape
    flat = punch_xy.reshape(-1, 2)
    if radius_mm is None:
        pitch = cKDTree(flat).query(flat, k=2)[0][:, 1] if flat.shape[0] > 1 else np.array([100.0])
        radius_mm = RADIUS_PITCHES * float(np.median(pitch))
    on_plate = contains(offset_convex(convex_outline(design_xy, "the design"), margin_mm), flat)
    normal = np.full(flat.shape[0], np.nan)
    vertical = np.full(flat.shape[0], np.nan)
    for i, near in enumerate(cKDTree(xy).query_ball_point(flat, radius_mm)):
        if on_plate[i] and len(near) >= MIN_POINTS:
            normal[i] = np.median(deviation[near])
            vertical[i] = np.median(deviation[near] / n_z[near])
    measured = np.isfinite(normal)
    gap = on_plate & ~measured
    if gap.any() and measured.sum() >= 3:
        # smooth fill: a thin-plate spline through the measured punch values
        for values in (normal, vertical):
            values[gap] = tps_fill(flat[measured], values[measured], flat[gap], smoothing=FILL_SMOOTHING)
    return vertical.reshape(rows, cols), normal.reshape(rows, cols), gap.reshape(rows, cols)


def punch_label(row: int, col: int, label_base: int = 1) -> str:
    """How a punch is named in messages, reports and pictures: ``"row 3, col 4"`` counted from ``label_base``
    (the press file's; :meth:`mppf.planning.press.PressConfig.punch_label` says the same)."""
    return f"row {int(row) + label_base}, col {int(col) + label_base}"


def short_label(row: int, col: int, label_base: int = 1) -> str:
    """The compact name of a punch in picture cells: ``"3,4"`` (row, col from ``label_base``)."""
    return f"{int(row) + label_base},{int(col) + label_base}"


def nearest_punch(punch_xy_mm: np.ndarray, xy_mm: np.ndarray, label_base: int = 1) -> str:
    """The name (:func:`punch_label`) of the punch of the grid (rows, cols, 2) nearest to press ``xy_mm`` (2,)."""
    distance = np.linalg.norm(punch_xy_mm - np.asarray(xy_mm, dtype=float)[None, None, :], axis=2)
    row, col = np.unravel_index(int(np.argmin(distance)), distance.shape)
    return punch_label(row, col, label_base)
