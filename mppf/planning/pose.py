"""The design's pose on the bed: the vertical offset and small tilt of least punch travel.

A tilt adds, to first order, a plane ``a x + b y`` to every tip height and an offset a
constant ``c``; the linear programme of :func:`minimax_offset` gives the plane that
minimises the largest travel within the stroke limits (see ``docs/planning.md``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.errors import LimitError
from mppf.core.transform import make_tf
from mppf.model.press import PressConfig
from mppf.planning.contact import PlacedSurface, tip_heights

MAX_TILT_DEG = 3.0
"""Largest tilt of the design against the bed that the stroke optimisation may choose."""

MIN_TILT_GAIN_MM = 1.0
"""A tilt is used only when it lowers the largest punch travel by at least this much."""

ACTIVE_SET_START = 8
"""Rows the tilt's linear programme starts from, per extreme (highest, lowest, closest to a limit)."""
ACTIVE_SET_ADD = 64
"""Most violated rows added to the programme per round."""
ACTIVE_SET_ROUNDS = 20
"""Rounds of the active set before the programme is solved on every row."""
ACTIVE_SET_TOL_MM = 1e-9
"""A row is violated when the programme's plane misses it by more than this (mm)."""


@dataclass(frozen=True)
class Pose:
    """The design's final pose and its strokes.

    Attributes
    ----------
    tf_adjust : (4, 4) float
        Press -> press correction (tilt, then offset) applied after registration.
    tilt_x_deg, tilt_y_deg : float
        Rotation about press x and y through the plate centre.
    offset_mm : float
        Vertical shift of the design after the tilt.
    upper_mm, lower_mm : (m,) float
        Final tip heights of the active punches.
    exact : (m,) bool
        Newton contact converged for both punches of the pair.
    contact_xy_mm : (2m, 2) float
        Where the upper, then the lower balls touch the mid-surface, seen from above.
    travel_mm : float
        Largest |tip height - flat-plate tip height| over both matrices.
    """

    tf_adjust: np.ndarray
    tilt_x_deg: float
    tilt_y_deg: float
    offset_mm: float
    upper_mm: np.ndarray
    lower_mm: np.ndarray
    exact: np.ndarray
    contact_xy_mm: np.ndarray
    travel_mm: float


def optimise_pose(placed: PlacedSurface, x_mm, y_mm, labels, press: PressConfig, thickness_mm: float,
                  centre_mm) -> Pose:
    """Vertical offset and small tilt that keep strokes in limits with the least travel.

    The travel of an active tip is its height minus its flat-plate height (upper t,
    lower 0). A tilt adds, to first order, a plane ``a x + b y`` to every tip height
    and an offset a constant ``c``; the linear programme of :func:`minimax_offset`
    gives the plane that minimises the largest travel within the stroke limits. The
    tilt is applied as a true rotation and the contact re-solved (twice, which
    converges the linearisation); the final offset is exact, since a vertical shift
    moves every tip by the same amount. A tilt is kept only when it lowers the
    largest travel by ``MIN_TILT_GAIN_MM`` or more.

    Parameters
    ----------
    placed : PlacedSurface
        The design's mid-surface after registration.
    x_mm, y_mm : (m,) float
        Axes of the active punches.
    labels : list of str
        "[row,col]" of each active punch, for error messages.
    press : PressConfig
    thickness_mm : float
    centre_mm : (3,) float
        Centre of the tilt (the plate centre).

    Raises
    ------
    LimitError
        No offset and tilt keep every stroke inside the press limits.
    """
    travels = _Travels.of(placed, x_mm, y_mm, press, thickness_mm)
    max_slope = np.tan(np.radians(MAX_TILT_DEG))
    # 1. the registered pose: the best level offset and the best small tilt
    tf = np.eye(4)
    dev, contact = travels.at(tf)
    level = travels.best(dev, max_slope=0.0)
    tilted = travels.best(dev, max_slope=max_slope)
    if tilted is None:
        raise _beyond_limits(dev, travels.low_mm, travels.high_mm, travels.flat_mm, labels)
    # 2. tilt only when it pays: applied as a true rotation, the contact solved again
    if level is None or level[3] - tilted[3] >= MIN_TILT_GAIN_MM:
        tf, dev, contact = _tilted(travels, tilted, centre_mm, max_slope)
    # 3. the final offset, exact: a vertical shift moves every tip alike
    final = travels.best(dev, max_slope=0.0)
    if final is None:  # the tilt iteration went astray: fall back to level, if the level pose is within limits
        tf = np.eye(4)
        dev, contact = travels.at(tf)
        final = level
        if final is None:
            raise _beyond_limits(dev, travels.low_mm, travels.high_mm, travels.flat_mm, labels)
    return _pose(tf, dev, contact, final[2], travels.flat_mm)


@dataclass(frozen=True)
class _Travels:
    """The travel of every active tip from its flat-plate height (upper t, lower 0) and its limits.

    Arrays are (2 m,): the m upper tips, then the m lower tips; heights in mm, press coordinates.
    """

    placed: PlacedSurface
    x_mm: np.ndarray  # (m,)
    y_mm: np.ndarray  # (m,)
    press: PressConfig
    thickness_mm: float
    flat_mm: np.ndarray  # (2 m,) the flat plate's tip heights
    low_mm: np.ndarray  # (2 m,) the least travel the stroke limits allow
    high_mm: np.ndarray  # (2 m,) the largest

    @classmethod
    def of(cls, placed: PlacedSurface, x_mm, y_mm, press: PressConfig, thickness_mm: float) -> _Travels:
        """The travels of the punches at ``x_mm``, ``y_mm`` ((m,) float) for the surface ``placed``."""
        x_mm = np.asarray(x_mm, dtype=float)
        y_mm = np.asarray(y_mm, dtype=float)
        m = len(x_mm)
        flat = np.concatenate([np.full(m, float(thickness_mm)), np.zeros(m)])
        low = np.concatenate([np.full(m, press.upper.min_mm), np.full(m, press.lower.min_mm)]) - flat
        high = np.concatenate([np.full(m, press.upper.max_mm), np.full(m, press.lower.max_mm)]) - flat
        return cls(placed, x_mm, y_mm, press, thickness_mm, flat, low, high)

    def at(self, tf):
        """Travels ((2 m,) mm) with the surface moved by ``tf`` ((4, 4), press -> press); and the contact:
        ((m,) bool exact at both tips, (2 m, 3) contact points in mm)."""
        moved = PlacedSurface(self.placed.surface, tf @ self.placed.tf_press_local)
        up, lo = tip_heights(moved, self.x_mm, self.y_mm, tip_radius_mm=self.press.tip_radius_mm,
                             thickness_mm=self.thickness_mm)
        return np.concatenate([up.tip_mm, lo.tip_mm]) - self.flat_mm, (up.exact & lo.exact,
                                                                        np.vstack([up.contact_mm, lo.contact_mm]))

    def best(self, dev, max_slope: float):
        """:func:`minimax_offset` of the travels ``dev`` ((2 m,) mm) within the limits."""
        xx, yy = np.concatenate([self.x_mm, self.x_mm]), np.concatenate([self.y_mm, self.y_mm])
        return minimax_offset(dev, xx, yy, self.low_mm, self.high_mm, max_slope=max_slope)


def _tilted(travels: _Travels, tilted, centre_mm, max_slope: float):
    """The tilt of least travel applied as true rotations about ``centre_mm`` (the contact solved again after
    each, at most three times): the pose ``tf`` (4, 4), the travels and the contact there."""
    tf = np.eye(4)
    for _ in range(3):
        tf = tilt_tf(tilted[0], tilted[1], centre_mm) @ tf
        dev, contact = travels.at(tf)
        tilted = travels.best(dev, max_slope=max_slope)
        if tilted is None or max(abs(tilted[0]), abs(tilted[1])) < 1e-7:
            break
    return tf, dev, contact


def _pose(tf, dev, contact, offset: float, flat) -> Pose:
    """The :class:`Pose` of ``tf`` ((4, 4)) shifted up by ``offset`` mm; ``dev`` (2 m,) travels, ``flat`` (2 m,)
    flat-plate tip heights (mm), ``contact`` as :meth:`_Travels.at`."""
    tf = make_tf(translation=[0.0, 0.0, offset]) @ tf
    dev = dev + offset
    rot = tf[:3, :3]
    m = len(dev) // 2
    return Pose(
        tf_adjust=tf,
        tilt_x_deg=float(np.degrees(np.arctan2(rot[2, 1], np.hypot(rot[2, 0], rot[2, 2])))),
        tilt_y_deg=float(np.degrees(np.arctan2(-rot[2, 0], rot[2, 2]))),
        offset_mm=float(offset),
        upper_mm=dev[:m] + flat[:m],
        lower_mm=dev[m:] + flat[m:],
        exact=contact[0],
        contact_xy_mm=contact[1][:, :2],
        travel_mm=float(np.abs(dev).max()),
    )


def _beyond_limits(dev, low, high, flat, labels) -> LimitError:
    """The error of a plate whose travel no offset and tilt keep inside the limits (the level offset's violations)."""
    c = -(dev.max() + dev.min()) / 2.0
    items = limit_violations(dev + c + flat, low + flat, high + flat,
                             [f"upper{lab}" for lab in labels] + [f"lower{lab}" for lab in labels])
    return stroke_limit_error(
        f"the plate needs strokes beyond the press limits (range of travel {np.ptp(dev):.0f} mm) "
        f"even with the best offset and a tilt up to {MAX_TILT_DEG:g} deg", items,
        int(np.count_nonzero((dev + c < low) | (dev + c > high))))


def tilt_tf(slope_x: float, slope_y: float, centre_mm) -> np.ndarray:
    """Rotation about a horizontal axis through ``centre_mm`` that adds ``slope_x * x +
    slope_y * y`` to the heights of a horizontal surface (to first order).

    Returns
    -------
    (4, 4) float
    """
    theta_y = -np.arcsin(np.clip(slope_x, -1, 1))  # about y: z' = -x sin(theta_y) + ...
    theta_x = np.arcsin(np.clip(slope_y, -1, 1))   # about x: z' = y sin(theta_x) + ...
    cy, sy = np.cos(theta_y), np.sin(theta_y)
    cx, sx = np.cos(theta_x), np.sin(theta_x)
    rot_y = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rot_x = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    centre = np.asarray(centre_mm, dtype=float)
    return make_tf(translation=centre) @ make_tf(rot_x @ rot_y) @ make_tf(translation=-centre)


def minimax_offset(dev_mm, x_mm, y_mm, low_mm, high_mm, *, max_slope: float):
    """Plane ``a x + b y + c`` added to all strokes that minimises the largest travel.

    Solves the linear programme: minimise s subject to
    ``-s <= dev_i + a x_i + b y_i + c <= s`` (travel of every active tip) and
    ``low_i <= dev_i + a x_i + b y_i + c <= high_i`` (stroke limits, expressed as
    travel), ``|a|, |b| <= max_slope``. With ``max_slope = 0`` (a pure offset) the
    answer is closed form: the mid-range offset, clamped to the limits.

    Parameters
    ----------
    dev_mm : (m,) float
        Travel of each active tip (height minus its flat-plate height), both matrices.
    x_mm, y_mm : (m,) float
        Punch axes.
    low_mm, high_mm : (m,) float
        Allowed travel range of each tip.
    max_slope : float
        0 for a pure vertical offset.

    Returns
    -------
    (a, b, c, s) : floats, or None when no plane keeps every stroke inside its limits.
    """
    if max_slope == 0.0:
        lo, hi = float(np.max(low_mm - dev_mm)), float(np.min(high_mm - dev_mm))
        if lo > hi + 1e-9:
            return None
        c = float(np.clip(-(dev_mm.max() + dev_mm.min()) / 2.0, lo, hi))
        return 0.0, 0.0, c, float(np.abs(dev_mm + c).max())
    # An active set: the programme on a few rows (the tips extreme for a level plane and for the
    # steepest tilts), then on those plus every row its answer violates, until it violates none. A
    # relaxation's optimum that meets every row is the full programme's; an infeasible relaxation
    # means an infeasible programme.
    scale = max(float(np.abs(np.concatenate([x_mm, y_mm])).max()), 1.0)  # x, y of order 1: well conditioned
    cols = np.column_stack([x_mm / scale, y_mm / scale])
    bound = max_slope * scale
    keep = _start_rows(dev_mm, cols, low_mm, high_mm, bound)
    for _ in range(ACTIVE_SET_ROUNDS):
        res = _solve_rows(dev_mm, cols, low_mm, high_mm, bound, keep)
        if res is None:
            return None
        a, b, c, s = res
        travel = dev_mm + cols @ np.array([a, b]) + c
        excess = np.max([travel - s, -travel - s, travel - high_mm, low_mm - travel], axis=0)
        bad = np.flatnonzero(excess > ACTIVE_SET_TOL_MM)
        if bad.size == 0:
            return a / scale, b / scale, c, s
        keep = np.union1d(keep, bad[np.argsort(-excess[bad])[:ACTIVE_SET_ADD]])
    res = _solve_rows(dev_mm, cols, low_mm, high_mm, bound, np.arange(len(dev_mm)))  # every row
    return None if res is None else (res[0] / scale, res[1] / scale, res[2], res[3])


def _start_rows(dev_mm, cols, low_mm, high_mm, bound: float) -> np.ndarray:
    """The rows the active set starts from: the highest and lowest tips under a level plane and the four
    steepest tilts, and the tips closest to their limits."""
    k = ACTIVE_SET_START
    keep = [np.argsort(high_mm - dev_mm)[:k], np.argsort(dev_mm - low_mm)[:k]]
    for sa, sb in ((0, 0), (1, 1), (1, -1), (-1, 1), (-1, -1)):
        order = np.argsort(dev_mm + bound * (sa * cols[:, 0] + sb * cols[:, 1]))
        keep += [order[:k], order[-k:]]
    return np.unique(np.concatenate(keep))


def _solve_rows(dev_mm, cols, low_mm, high_mm, bound: float, rows):
    """The linear programme of :func:`minimax_offset` on some rows (scaled x, y); (a', b', c, s) or None."""
    from scipy.optimize import linprog

    dev, low, high = dev_mm[rows], low_mm[rows], high_mm[rows]
    plane = np.column_stack([cols[rows], np.ones(len(rows))])
    ones, zero = np.ones(len(rows)), np.zeros(len(rows))
    # variables (a', b', c, s); rows: A z <= b_ub
    a_ub = np.vstack([
        np.column_stack([plane, -ones]),    # dev + plane <= s
        np.column_stack([-plane, -ones]),   # -(dev + plane) <= s
        np.column_stack([plane, zero]),     # dev + plane <= high
        np.column_stack([-plane, zero]),    # dev + plane >= low
    ])
    b_ub = np.concatenate([-dev, dev, high - dev, dev - low])
    bounds = [(-bound, bound), (-bound, bound), (None, None), (0, None)]
    res = linprog([0, 0, 0, 1], A_ub=a_ub, b_ub=b_ub, bounds=bounds, method="highs")
    return tuple(float(x) for x in res.x) if res.status == 0 else None


def limit_violations(values_mm, low_mm, high_mm, labels) -> list[str]:
    """Human-readable list of values outside [low, high] (at most 10)."""
    bad = np.flatnonzero((values_mm < low_mm - 1e-6) | (values_mm > high_mm + 1e-6))
    return [f"{labels[i]} {values_mm[i]:.1f} mm (limits {low_mm[i]:.0f}..{high_mm[i]:.0f})" for i in bad[:10]]


def stroke_limit_error(what: str, items: list[str], total: int) -> LimitError:
    """The LimitError raised when strokes cannot be kept inside the press limits."""
    more = f" and {total - len(items)} more" if total > len(items) else ""
    return LimitError(
        f"{what}: {'; '.join(items)}{more}",
        hint="use a press with longer strokes, a thinner or flatter plate, or split the plate",
    )
