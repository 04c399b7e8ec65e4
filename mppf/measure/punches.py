"""The plate's deviation at each punch of the press: measured near its axis, filled in across scan gaps."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from mppf.core.grid import tps_fill
from mppf.core.polygon import contains, convex_outline, distance_to_outline, offset_convex
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


EDGE_BAND_MM = 5.0
"""Points this close to the net plate's outline are its edge (mm)."""


def edge_deviations(punch_x_mm, punch_y_mm, active, points_xy_mm, deviation_mm) -> np.ndarray:
    """Mean deviation of the net plate's edge beyond each outer-row punch.

    The outer-row punches are the first and the last active punch of each column; the edge
    beyond one is the points within :data:`EDGE_BAND_MM` of the net outline, within half a
    column pitch of its axis in x (the axis held to the net plate's x range: a column in the
    trim margin takes the corner) and at most one row pitch beyond it in y.

    Parameters
    ----------
    punch_x_mm : (cols,) float
    punch_y_mm : (rows,) float
    active : (rows, cols) bool
    points_xy_mm : (n, 2) float
        The net plate's points (press x, y), e.g. the design's.
    deviation_mm : (n,) float
        Their deviation (plate above the design positive, plane removed; NaN unknown).

    Returns
    -------
    (rows, cols) float
        NaN where the punch is not an outer-row one or no edge point lies beyond it.
    """
    act = np.asarray(active, dtype=bool)
    xs, ys = np.asarray(punch_x_mm, dtype=float), np.asarray(punch_y_mm, dtype=float)
    xy = np.asarray(points_xy_mm, dtype=float)
    dev = np.asarray(deviation_mm, dtype=float)
    keep = np.isfinite(dev)
    xy, dev = xy[keep], dev[keep]
    out = np.full(act.shape, np.nan)
    if len(xy) < 3 or len(xs) < 2 or len(ys) < 2:
        return out
    edge = distance_to_outline(convex_outline(xy, "the net plate's points"), xy) <= EDGE_BAND_MM
    exy, edev = xy[edge], dev[edge]
    half_x, pitch_y = 0.5 * float(np.min(np.abs(np.diff(xs)))), float(np.min(np.abs(np.diff(ys))))
    x_lo, x_hi = float(xy[:, 0].min()), float(xy[:, 0].max())
    for c in range(act.shape[1]):
        rows = np.flatnonzero(act[:, c])
        if rows.size == 0:
            continue
        x = min(max(xs[c], x_lo), x_hi)
        near_x = np.abs(exy[:, 0] - x) <= half_x
        for r, side in ((rows[0], np.sign(ys[rows[0]] - ys[rows[-1]])), (rows[-1], np.sign(ys[rows[-1]] - ys[rows[0]]))):
            if side == 0:
                continue
            beyond = (exy[:, 1] - ys[r]) * side
            use = near_x & (beyond >= 0.0) & (beyond <= pitch_y)
            if use.any():
                out[r, c] = float(np.mean(edev[use]))
    return out


def edge_at_punches(punch_xy_mm, tf_press_design, skin, dev, use_net, on_plate) -> np.ndarray:
    """The net plate's measured edge beyond each outer-row punch (:func:`edge_deviations`), along press z.

    Parameters
    ----------
    punch_xy_mm : (rows, cols, 2) float, mm
    tf_press_design : (4, 4) float
    skin, dev
        As :func:`punch_deviations`.
    use_net : (n,) bool
        The measured points of the net plate that count (not margin, outside or outliers).
    on_plate : (rows, cols) bool
        The punches under the plate (their deviation known).

    Returns
    -------
    (rows, cols) float, mm
        Positive = plate above the design; NaN where the punch is not an outer-row one or no
        measured edge point lies beyond it.
    """
    press_local = np.asarray(tf_press_design, dtype=float) @ skin.frame.tf_world_local
    uv = dev.uv[use_net]
    n_z = apply_rotation(press_local, skin.fitted.surface.normals(uv[:, 0], uv[:, 1]))[:, 2] * skin.sign
    foot_press = apply_tf(press_local, np.asarray(dev.feet.xyz, dtype=float)[use_net])
    grid = np.asarray(punch_xy_mm, dtype=float)
    return edge_deviations(grid[0, :, 0], grid[:, 0, 1], on_plate, foot_press[:, :2],
                           dev.deviation_mm[use_net] / np.maximum(n_z, SLOPE_FLOOR))


def punch_label(row: int, col: int, label_base: int = 1) -> str:
    """How a punch is named in messages, reports and pictures: ``"row 3, col 4"`` counted from ``label_base``
    (the press file's; :meth:`mppf.model.press.PressConfig.punch_label` says the same)."""
    return f"row {int(row) + label_base}, col {int(col) + label_base}"


def short_label(row: int, col: int, label_base: int = 1) -> str:
    """The compact name of a punch in picture cells: ``"3,4"`` (row, col from ``label_base``)."""
    return f"{int(row) + label_base},{int(col) + label_base}"


def nearest_punch(punch_xy_mm: np.ndarray, xy_mm: np.ndarray, label_base: int = 1) -> str:
    """The name (:func:`punch_label`) of the punch of the grid (rows, cols, 2) nearest to press ``xy_mm`` (2,)."""
    distance = np.linalg.norm(punch_xy_mm - np.asarray(xy_mm, dtype=float)[None, None, :], axis=2)
    row, col = np.unravel_index(int(np.argmin(distance)), distance.shape)
    return punch_label(row, col, label_base)
