"""What the press can make of a plate at all, before any tolerance is promised.

The punches hold the plate only at their axes. Beyond the outer punches the net plate
overhangs, and a free edge carries no bending moment: there the plate follows the tangent of
the last punches, not the design. The design departs from that straight extension by about
``k d^2 / 2`` over an overhang ``d`` at a design curvature ``k`` across the edge; no stroke
can change it. :func:`reach_estimate` puts that next to the tolerance, with the punch pitch
and the room the planned strokes leave to the stroke limits, so the plan says what it can
reach and a loop that ends short of the tolerance can say why.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from mppf.core.polygon import contains
from mppf.core.transform import apply_tf


@dataclass(frozen=True)
class Reach:
    """What the press can make of a planned plate (mm).

    Attributes
    ----------
    overhang_mm : float
        Largest distance of the net plate beyond the outer punch axes (along press x or y).
    edge_error_mm : float
        Largest departure of the design from the straight extension of the plate beyond the outer
        punches (``k d^2 / 2``): the form error no stroke can remove there.
    edge_xy_mm : (2,) float
        Where it lies (press x, y).
    pitch_mm : (2,) float
        Punch pitch along press x and y.
    stroke_room_mm : float
        Smallest room between the planned final strokes and the stroke limits (either matrix).
    tolerance_mm : float
        The form tolerance it is judged against.
    """

    overhang_mm: float
    edge_error_mm: float
    edge_xy_mm: tuple
    pitch_mm: tuple
    stroke_room_mm: float
    tolerance_mm: float

    @property
    def reachable(self) -> bool:
        """The edge beyond the outer punches leaves at most half the tolerance (the rest is the correction's)."""
        return self.edge_error_mm <= 0.5 * self.tolerance_mm

    @property
    def text(self) -> str:
        """One line for the plan."""
        head = (f"reach: the net plate overhangs the outer punches by up to {self.overhang_mm:.0f} mm; the free edge "
                f"there departs from the design by up to {self.edge_error_mm:.2f} mm (at x, y = "
                f"{self.edge_xy_mm[0]:.0f}, {self.edge_xy_mm[1]:.0f} mm); punch pitch {self.pitch_mm[0]:.0f} x "
                f"{self.pitch_mm[1]:.0f} mm; {self.stroke_room_mm:.0f} mm of stroke left")
        if self.reachable:
            return f"{head}: the tolerance of {self.tolerance_mm:g} mm is within reach"
        return (f"{head}: the tolerance of {self.tolerance_mm:g} mm may not be reached at that edge (lay the plate so "
                "a punch row lies nearer it, or finish the edge by hand)")

    def to_dict(self) -> dict:
        """JSON-able, with ``reachable`` and ``text``."""
        return {**asdict(self), "edge_xy_mm": list(self.edge_xy_mm), "pitch_mm": list(self.pitch_mm),
                "reachable": self.reachable, "text": self.text}


def reach_estimate(press, job, design_points, tolerance_mm: float) -> Reach:
    """The reach of a planned (not sectional) plate.

    Parameters
    ----------
    press : PressConfig
    job : Job
        The first cycle's job (its layout, pose and final strokes).
    design_points : (n, 3) float
        The design surface in its own coordinates (mm).
    tolerance_mm : float

    Returns
    -------
    Reach
    """
    final = job.steps[-1]
    act = np.asarray(final.active, dtype=bool)
    xy_z = apply_tf(job.tf_press_design, np.asarray(design_points, dtype=float))
    net = job.layout.net_outline_mm if job.layout is not None else None
    if net is not None and len(net) >= 3:
        xy_z = xy_z[contains(net, xy_z[:, :2], tolerance_mm=1e-6)]
    px, py = np.asarray(press.punch_x_mm, float), np.asarray(press.punch_y_mm, float)
    dx, dy = _overhang(xy_z[:, 0], xy_z[:, 1], px, py, act)
    kxx, kyy = _curvatures(xy_z)
    error = 0.5 * (abs(kxx) * dx**2 + abs(kyy) * dy**2)
    worst = int(np.argmax(error)) if error.size else 0
    room = _stroke_room(press, final, act)
    pitch = (float(np.median(np.diff(px))) if px.size > 1 else 0.0, float(np.median(np.diff(py))) if py.size > 1 else 0.0)
    return Reach(float(max(dx.max(initial=0.0), dy.max(initial=0.0))), float(error.max(initial=0.0)),
                 (float(xy_z[worst, 0]), float(xy_z[worst, 1])) if error.size else (0.0, 0.0), pitch, room,
                 float(tolerance_mm))


def _overhang(x, y, px, py, act):
    """Distance (n,) of each point beyond the active punches of its nearest row (along x) and column (along y)."""
    row = np.abs(y[:, None] - py[None, :]).argmin(axis=1)
    col = np.abs(x[:, None] - px[None, :]).argmin(axis=1)
    lo_x = np.array([px[act[r]].min() if act[r].any() else np.nan for r in range(act.shape[0])])
    hi_x = np.array([px[act[r]].max() if act[r].any() else np.nan for r in range(act.shape[0])])
    lo_y = np.array([py[act[:, c]].min() if act[:, c].any() else np.nan for c in range(act.shape[1])])
    hi_y = np.array([py[act[:, c]].max() if act[:, c].any() else np.nan for c in range(act.shape[1])])
    dx = np.nan_to_num(np.maximum(0.0, np.maximum(lo_x[row] - x, x - hi_x[row])))
    dy = np.nan_to_num(np.maximum(0.0, np.maximum(lo_y[col] - y, y - hi_y[col])))
    return dx, dy


def _curvatures(points) -> tuple[float, float]:
    """Curvatures z_xx, z_yy (1/mm) of the best quadric z(x, y) through the points."""
    if len(points) < 6:
        return 0.0, 0.0
    x, y, z = (points[:, k] - points[:, k].mean() for k in range(3))
    basis = np.column_stack([np.ones_like(x), x, y, x * x, x * y, y * y])
    coef = np.linalg.lstsq(basis, z, rcond=None)[0]
    return 2.0 * float(coef[3]), 2.0 * float(coef[5])


def _stroke_room(press, step, act) -> float:
    """Smallest room (mm) between a step's strokes and the stroke limits at the active punches."""
    rooms = []
    for values, limits in ((step.upper_mm, press.upper), (step.lower_mm, press.lower)):
        v = np.asarray(values, dtype=float)[act]
        rooms.append(np.min(np.minimum(limits.max_mm - v, v - limits.min_mm), initial=np.inf))
    return float(min(rooms))
