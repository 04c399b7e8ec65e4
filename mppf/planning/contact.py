"""Ball-tip contact: the tip height of every punch touching a plate, solved exactly.

A plate of thickness ``t`` is described by its mid-surface. The bottom skin is the
mid-surface offset by ``t/2`` against the (upward) normal, the top skin by ``t/2``
along it. A ball of radius ``r`` touching a skin is a ball of radius ``R = r + t/2``
touching the mid-surface, so only the mid-surface is needed.

For a punch on the vertical axis through ``(x0, y0)`` the ball centre height is the
drop-cutter value

    upper:  zc = max over mid-surface points p with |p_xy - a| < R of  p_z + sqrt(R^2 - |p_xy - a|^2)
    lower:  zc = min over the same points of                           p_z - sqrt(R^2 - |p_xy - a|^2)

and the tip height is ``zc - r`` (upper: the bottom of its ball) or ``zc + r`` (lower:
the top of its ball). The maximiser is the contact point ``p`` where the ball centre
lies on the surface normal: ``p + s R n(p)`` is on the axis, ``s = +1`` upper, ``-1``
lower. :func:`tip_heights` samples the drop-cutter value on a small patch around the
axis, then solves ``(p + s R n)_xy = a`` with Newton's method (analytic Jacobian from
the second derivatives of the height field), so the result is exact, not limited by
the sampling. See ``docs/planning.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from mppf.core.errors import GeometryError
from mppf.core.transform import apply_tf
from mppf.core.validate import check_positive

SAMPLES_PER_SIDE = 7
"""Samples per side of the patch searched around each punch axis before Newton (0.5 R apart: the best
one starts Newton close enough to its root; 11, 0.3 R apart, gave the same tips to 2e-10 mm on real
hull plates at 1.6 times the cost)."""

PATCH_HALF_WIDTH = 1.5
"""Half width of the searched (u, v) patch, in units of R = r + t/2."""

NEWTON_ITERATIONS = 20
NEWTON_TOL_MM = 1e-9
AXIS_FOOT_TOL_MM = 1e-10
"""The axis-foot iteration stops when no point moves more than this along its axis (mm)."""


@dataclass(frozen=True, eq=False)
class PlacedSurface:
    """A height field ``w = z(u, v)`` in a local frame, placed in press coordinates.

    Attributes
    ----------
    surface : object
        Anything with ``derivatives(u, v) -> (z, zu, zv, zuu, zuv, zvv)`` for (m,)
        arrays of local coordinates (mm); e.g. a :class:`mppf.geometry.surface` surface.
    tf_press_local : (4, 4) float
        Maps the surface's local frame into press coordinates.
    """

    surface: object
    tf_press_local: np.ndarray

    def geometry(self, u, v):
        """Press-coordinate point and derivatives of r(u, v) = tf (u, v, z(u, v)).

        Returns
        -------
        p, pu, pv, puu, puv, pvv : (m, 3) float
        """
        u = np.asarray(u, dtype=float)
        v = np.asarray(v, dtype=float)
        z, zu, zv, zuu, zuv, zvv = (np.broadcast_to(np.asarray(a, dtype=float), u.shape)[..., None]
                                    for a in self.surface.derivatives(u, v))
        tf = np.asarray(self.tf_press_local, dtype=float)
        eu, ev, ew = tf[:3, 0], tf[:3, 1], tf[:3, 2]  # the local axes in press coordinates
        p = u[..., None] * eu + v[..., None] * ev + z * ew + tf[:3, 3]
        return p, eu + zu * ew, ev + zv * ew, zuu * ew, zuv * ew, zvv * ew

    def points(self, u, v) -> np.ndarray:
        """(m, 3) press points of the surface at local (u, v)."""
        z = np.asarray(self.surface.evaluate(u, v), dtype=float)
        return apply_tf(self.tf_press_local, np.column_stack([u, v, np.broadcast_to(z, np.shape(u))]))

    def axis_foot(self, x_mm, y_mm, iterations: int = 8) -> tuple[np.ndarray, np.ndarray]:
        """Local (u, v) where vertical press lines through (x, y) cross the surface.

        Fixed-point iteration along the line; exact enough as a start for Newton.
        """
        tf = np.asarray(self.tf_press_local, dtype=float)
        rot, shift = tf[:3, :3], tf[:3, 3]
        line0 = (np.column_stack([x_mm, y_mm, np.zeros_like(x_mm)]) - shift) @ rot  # local
        direction = rot[2]  # press z expressed in local coordinates
        if abs(direction[2]) < 0.5:
            raise GeometryError(
                f"the plate is tilted {np.degrees(np.arccos(abs(direction[2]))):.0f} deg from the press bed",
                hint="the design must lie nearly horizontal after registration; check the flat plate",
            )
        s = np.zeros(len(line0))
        for _ in range(iterations):
            u = line0[:, 0] + s * direction[0]
            v = line0[:, 1] + s * direction[1]
            z = np.asarray(self.surface.evaluate(u, v), dtype=float)
            s, previous = (z - line0[:, 2]) / direction[2], s
            if np.all(np.abs(s - previous) < AXIS_FOOT_TOL_MM):
                break
        return line0[:, 0] + s * direction[0], line0[:, 1] + s * direction[1]


@dataclass(frozen=True)
class Contact:
    """Tip heights of one matrix.

    Attributes
    ----------
    tip_mm : (m,) float
        Tip height (upper: bottom of ball, lower: top of ball), press z, mm.
    contact_mm : (m, 3) float
        Contact point on the mid-surface, press coordinates.
    exact : (m,) bool
        True where Newton converged to the contact (False: the sampled value was kept).
    """

    tip_mm: np.ndarray
    contact_mm: np.ndarray
    exact: np.ndarray


def _cross(a, b):
    """Row-wise cross product of (m, 3) arrays (np.cross without its per-call overhead)."""
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def _normal_and_derivatives(pu, pv, puu, puv, pvv):
    """Unit normal (oriented up) and its u, v derivatives, all (m, 3)."""
    big_n = _cross(pu, pv)
    big_nu = _cross(puu, pv) + _cross(pu, puv)
    big_nv = _cross(puv, pv) + _cross(pu, pvv)
    sign = np.where(big_n[:, 2] >= 0, 1.0, -1.0)[:, None]
    big_n, big_nu, big_nv = big_n * sign, big_nu * sign, big_nv * sign
    norm = np.linalg.norm(big_n, axis=1, keepdims=True)
    n = big_n / norm
    nu = (big_nu - n * np.sum(n * big_nu, axis=1, keepdims=True)) / norm
    nv = (big_nv - n * np.sum(n * big_nv, axis=1, keepdims=True)) / norm
    return n, nu, nv


def tip_heights(placed: PlacedSurface, x_mm, y_mm, *, tip_radius_mm: float,
                thickness_mm: float) -> tuple[Contact, Contact]:
    """Tip heights of the upper and lower punches on vertical axes through (x, y).

    Parameters
    ----------
    placed : PlacedSurface
        The plate's mid-surface in press coordinates.
    x_mm, y_mm : (m,) float
        Punch axes, press coordinates.
    tip_radius_mm, thickness_mm : float

    Returns
    -------
    upper, lower : Contact
        Upper punches touch the top skin from above, lower punches the bottom skin
        from below.
    """
    check_positive("the tip radius", tip_radius_mm, unit="mm")
    check_positive("the plate thickness", thickness_mm, unit="mm")
    x_mm = np.asarray(x_mm, dtype=float).reshape(-1)
    y_mm = np.asarray(y_mm, dtype=float).reshape(-1)
    m = len(x_mm)
    big_r = tip_radius_mm + thickness_mm / 2.0
    axis = np.column_stack([x_mm, y_mm])

    # 1. Where each axis crosses the surface, in local (u, v).
    u0, v0 = placed.axis_foot(x_mm, y_mm)
    # 2. A patch of samples around it: the drop-cutter value there bounds the answer.
    offsets = np.linspace(-PATCH_HALF_WIDTH * big_r, PATCH_HALF_WIDTH * big_r, SAMPLES_PER_SIDE)
    du, dv = (g.reshape(-1) for g in np.meshgrid(offsets, offsets))
    us = u0[:, None] + du[None, :]
    vs = v0[:, None] + dv[None, :]
    pts = placed.points(us.reshape(-1), vs.reshape(-1)).reshape(m, -1, 3)
    d2 = np.sum((pts[:, :, :2] - axis[:, None, :]) ** 2, axis=2)
    reach = d2 < big_r**2
    if not np.all(reach.any(axis=1)):
        raise GeometryError("no surface point within reach of a punch ball",
                            hint="the surface is too steep for the press; check the registration")
    rise = np.sqrt(np.where(reach, big_r**2 - d2, 0.0))
    return _solve_sides(placed, axis, _Patch(us, vs, pts, rise, reach), big_r, tip_radius_mm)


class _Patch(NamedTuple):
    """The samples around each of m punch axes (k per axis), :func:`tip_heights` step 2."""

    us: np.ndarray  # (m, k) local u of each sample
    vs: np.ndarray  # (m, k) local v
    pts: np.ndarray  # (m, k, 3) the surface points there, press coordinates, mm
    rise: np.ndarray  # (m, k) height of the ball centre above the point where the ball reaches it, mm (0 beyond)
    reach: np.ndarray  # (m, k) bool: the point is within the ball's reach (radius R) of the axis


def _solve_sides(placed, axis, patch: _Patch, big_r: float, tip_radius_mm: float) -> tuple[Contact, Contact]:
    """Best sample, then Newton on (p + s R n)_xy = axis, the upper (s = +1) and lower (s = -1) side at once.

    ``axis`` (m, 2) are the punch axes, ``big_r`` = tip radius + t / 2 (mm). The sides' rows are stacked
    (upper rows first) so each iteration evaluates the surface once.
    """
    us, vs, pts, rise, reach = patch
    m = len(axis)
    s = np.repeat([1.0, -1.0], m)
    z, rows = pts[:, :, 2], np.arange(m)
    best_up = np.argmax(np.where(reach, z + rise, -np.inf), axis=1)  # maximise s * zc
    best_lo = np.argmax(np.where(reach, rise - z, -np.inf), axis=1)
    sampled = np.concatenate([z[rows, best_up] + rise[rows, best_up], -(rise[rows, best_lo] - z[rows, best_lo])])
    axis2 = np.vstack([axis, axis])
    start_u = np.concatenate([us[rows, best_up], us[rows, best_lo]])
    start_v = np.concatenate([vs[rows, best_up], vs[rows, best_lo]])
    p, n = _newton(placed, s[:, None] * big_r, axis2, start_u, start_v, big_r)
    centre = p + s[:, None] * big_r * n
    converged = np.all(np.abs(centre[:, :2] - axis2) < 1e-6, axis=1)
    # The Newton point is a genuine touching position, so it is kept when it is at
    # least as far as the sampled value (always, unless it found another local contact).
    exact = converged & (s * centre[:, 2] >= s * sampled - 1e-9)
    zc = np.where(exact, centre[:, 2], sampled)
    contact = np.where(exact[:, None], p, np.concatenate([pts[rows, best_up], pts[rows, best_lo]]))
    tip = zc - s * tip_radius_mm
    return (Contact(tip_mm=tip[:m], contact_mm=contact[:m], exact=exact[:m]),
            Contact(tip_mm=tip[m:], contact_mm=contact[m:], exact=exact[m:]))


def _newton(placed, signed_r, axis, u, v, big_r):
    """Newton iterations on (p + s R n)_xy = axis from (u, v); ``signed_r`` (k, 1) is s R.

    Returns
    -------
    p, n : (k, 3) float
        The surface point and unit normal at the last (u, v), press coordinates.
    """
    for _ in range(NEWTON_ITERATIONS):
        p, pu, pv, puu, puv, pvv = placed.geometry(u, v)
        n, nu, nv = _normal_and_derivatives(pu, pv, puu, puv, pvv)
        resid = (p + signed_r * n)[:, :2] - axis
        if np.all(np.abs(resid) < NEWTON_TOL_MM):
            return p, n
        ju = (pu + signed_r * nu)[:, :2]
        jv = (pv + signed_r * nv)[:, :2]
        det = ju[:, 0] * jv[:, 1] - jv[:, 0] * ju[:, 1]
        det = np.where(np.abs(det) < 1e-12, 1e-12, det)
        step_u = (jv[:, 1] * resid[:, 0] - jv[:, 0] * resid[:, 1]) / det
        step_v = (-ju[:, 1] * resid[:, 0] + ju[:, 0] * resid[:, 1]) / det
        length = np.hypot(step_u, step_v)
        scale = np.minimum(1.0, 0.5 * big_r / np.maximum(length, 1e-300))
        u = u - scale * step_u
        v = v - scale * step_v
    p, pu, pv, puu, puv, pvv = placed.geometry(u, v)
    return p, _normal_and_derivatives(pu, pv, puu, puv, pvv)[0]
