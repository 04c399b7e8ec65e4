"""The border check of a sectional plan: the design recovered from each section's strokes, compared where
sections meet (:func:`border_steps`), and the warnings of sections that step (:func:`border_warnings`).

See ``docs/sections.md``, "The design recovered from the strokes, and the border check".
"""

from __future__ import annotations

import numpy as np

from mppf.core.transform import apply_tf, invert_tf
from mppf.model.job_sections import Section
from mppf.model.press import PressConfig


def recovered_residual(press: PressConfig, fitted, section: Section, thickness_mm: float) -> np.ndarray:
    """(rows, cols): the design recovered from a section's final strokes, as its height above the design (mm).

    The tips' mid height (upper + lower) / 2 at each active punch axis, taken back into the design's
    own frame (``tf_press_design`` inverted), minus the design surface there; NaN at parked punches.
    """
    act = section.steps[-1].active
    residual = np.full(press.shape, np.nan)
    residual[act] = _height_above(fitted, _recovered_points(press, section))[1]
    return residual


def _recovered_points(press: PressConfig, section: Section) -> np.ndarray:
    """(m, 3): the tips' mid points of a section's final strokes at its active punch axes, in the design's frame."""
    final = section.steps[-1]
    gx, gy = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    act = final.active
    mid = np.column_stack([gx[act], gy[act], 0.5 * (final.upper_mm[act] + final.lower_mm[act])])
    return apply_tf(invert_tf(section.tf_press_design), mid)


def _touched_points(press: PressConfig, section: Section, thickness_mm: float) -> np.ndarray:
    """(2 m, 3): where the two balls of each active punch pair touch the plate's mid-surface, in the design's frame.

    The ball centres lie on the axis, ``r + t/2`` from the mid-surface along its normal; the normal is
    that of the tips' mid heights (their slope between neighbouring punches). Unlike the mid point of
    the tips on the axis, which lies off a curved surface by about ``k (r + t/2)^2 tan^2(slope) / 2``
    (0.5 mm on a plate over-bent to R 2.95 m and sloping 35 deg at the bed's edge), these points lie on it.
    The slope is one-sided next to parked punches; a punch with no active neighbour along an axis
    gives the mid point instead.
    """
    final = section.steps[-1]
    gx, gy = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    act = final.active
    mid = 0.5 * (final.upper_mm + final.lower_mm)
    slope_y, slope_x = _slope(mid, press.pitch_y_mm, 0), _slope(mid, press.pitch_x_mm, 1)
    normal = np.stack([-slope_x, -slope_y, np.ones(press.shape)], axis=-1)
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    reach = press.tip_radius_mm + thickness_mm / 2.0
    known = np.isfinite(normal[..., 0])
    normal = np.where(known[..., None], normal, 0.0)
    upper = np.stack([gx, gy, final.upper_mm + press.tip_radius_mm], axis=-1) - reach * normal
    lower = np.stack([gx, gy, final.lower_mm - press.tip_radius_mm], axis=-1) + reach * normal
    centre = np.stack([gx, gy, mid], axis=-1)
    upper, lower = np.where(known[..., None], upper, centre), np.where(known[..., None], lower, centre)
    return apply_tf(invert_tf(section.tf_press_design), np.vstack([upper[act], lower[act]]))


def _slope(grid, pitch_mm: float, axis: int) -> np.ndarray:
    """d grid / d axis: central differences, one-sided next to NaN (parked) or the grid's edge; NaN with neither."""
    padded = np.moveaxis(np.pad(np.moveaxis(grid, axis, 0), ((1, 1), (0, 0)), constant_values=np.nan), 0, axis)
    n = grid.shape[axis]
    before = np.take(padded, range(n), axis=axis)
    after = np.take(padded, range(2, n + 2), axis=axis)
    central = (after - before) / (2.0 * pitch_mm)
    forward, backward = (after - grid) / pitch_mm, (grid - before) / pitch_mm
    return np.where(np.isfinite(central), central, np.where(np.isfinite(forward), forward, backward))


def _height_above(fitted, points):
    """Local (u, v) (m, 2) of ``points`` (m, 3, world mm) in a fit's frame, and their heights above its surface (m,)."""
    local = fitted.frame.to_local(points)
    return local[:, :2], local[:, 2] - fitted.surface.evaluate(local[:, 0], local[:, 1])


def border_steps(press, planned, thickness_mm: float) -> list[float]:
    """Per section: the largest step of the recovered design at its border with the plate formed before it.

    At the section's outermost punches (first and last row and column of the bed) beyond which an
    earlier section's bed reaches (:func:`_edge_beyond`), the plate just beyond stays as that section left
    it: the points where the
    balls of both touch the plate (:func:`_touched_points`, in the design's frame) must lie on one
    surface there.
    Compared at the same place: in the frame of the surface the section presses, the earlier
    section's heights above it are interpolated (linearly over its punches, on a smooth residual) at
    this section's border punches. (Not punch by punch: on a strongly bent plate the punches of two
    sections shifted by whole pitches meet the formed plate tens of mm apart.) Measured against the
    last earlier section covering each punch.
    """
    from scipy.interpolate import LinearNDInterpolator

    points = [_touched_points(press, p["section"], thickness_mm) for p in planned]
    reach = 1.5 * max(press.pitch_x_mm, press.pitch_y_mm)
    steps = []
    for k, p in enumerate(planned):
        act = p["section"].steps[-1].active
        uv, height = _height_above(p["fitted"], points[k])
        last = np.full(int(2 * act.sum()), np.nan)
        lo, hi = uv.min(axis=0) - reach, uv.max(axis=0) + reach
        for j in range(k):
            edge = _edge_beyond(press, p["centre"], planned[j]["centre"])
            border = np.concatenate([edge[act], edge[act]])  # the upper balls' points, then the lower balls'
            uv_j, height_j = _height_above(p["fitted"], points[j])
            near = np.all((uv_j >= lo) & (uv_j <= hi), axis=1)
            if not border.any() or near.sum() < 3 or _collinear(uv_j[near]):
                continue  # no overlap area to interpolate over (e.g. one line of punches)
            there = np.full(len(last), np.nan)
            there[border] = LinearNDInterpolator(uv_j[near], height_j[near])(uv[border])
            last = np.where(np.isfinite(there), there, last)
        diff = np.abs(height - last)
        steps.append(float(np.nanmax(diff)) if np.isfinite(diff).any() else 0.0)
    return steps


def _edge_beyond(press: PressConfig, centre_mm, earlier_centre_mm) -> np.ndarray:
    """(rows, cols) bool: this section's outermost punch rows and columns beyond which the earlier section's bed
    reaches (by a pitch or more): where the plate just beyond the border is plate the earlier section formed.

    Where both beds end on the same line (two sections side by side across, at the same place along), the plate
    beyond is formed by neither, and the two sections' strokes there are the transition between them, not a border.
    """
    shift = np.asarray(earlier_centre_mm, dtype=float) - np.asarray(centre_mm, dtype=float)
    pitch = np.array([press.pitch_x_mm, press.pitch_y_mm])
    edge = np.zeros(press.shape, dtype=bool)
    ends = {(0, -1.0): (slice(None), 0), (0, 1.0): (slice(None), -1), (1, -1.0): (0, slice(None)),
            (1, 1.0): (-1, slice(None))}
    for (axis, side), where in ends.items():
        if side * shift[axis] >= pitch[axis] - 1e-6:  # the earlier bed reaches a pitch or more past this border
            edge[where] = True
    return edge


def _collinear(uv, tol_mm: float = 1e-6) -> bool:
    """True when the points (m, 2) mm lie on one line (or one point): no triangle spans them."""
    centred = uv - uv.mean(axis=0)
    return bool(np.linalg.svd(centred, compute_uv=False)[-1] <= tol_mm)


BORDER_STEP_LIMIT_MM = 1.0
"""A section whose recovered design steps more than this (mm) at its border with the plate formed before it
is warned of: the press would leave a step or kink there (see ``docs/sections.md``, "Not yet done")."""


def border_warnings(border_mm, springback: bool) -> list[str]:
    """The warnings of a sectional plan whose sections step at their borders (one per such section)."""
    out = []
    for index, step in enumerate(border_mm, start=1):
        if step > BORDER_STEP_LIMIT_MM:
            why = (" (the sections' fits follow the plate's one over-bent target only approximately where its "
                   "curvature varies strongly: plan without --springback and let the loop correct, or check "
                   "the plan)") if springback else ""
            out.append(f"section {index}: its strokes step by {step:.1f} mm at its border with the plate formed "
                       f"before it (limit {BORDER_STEP_LIMIT_MM:g} mm): the press would leave a step or kink "
                       f"there{why}")
    return out
