"""Localization: the foot point of each point on a plate surface z = D(u, v).

For a point p = T r* (the paper's notation: r* a measured or press point, T the 4x4
transform from registration into the surface's local frame) the foot point
r = (u, v, D(u, v)) solves the corrected paper eq. (2.11):

    F1 = (p - r) . (1, 0, zu) = 0,   F2 = (p - r) . (0, 1, zv) = 0,

i.e. p - r is orthogonal to both surface tangents (the homogeneous fourth component
of eq. 2.13-2.16 contributes nothing). F = (F1, F2) is minus the gradient of
f(u, v) = |p - r|^2 / 2, so the foot point is a minimum of f. It is found by a
vectorized, damped Newton-Raphson iteration on all points at once:

- start at the vertical projection (u, v) = (p_u, p_v);
- Newton step with the Hessian of f, H = [[1 + zu^2 - d zuu, zu zv - d zuv],
  [zu zv - d zuv, 1 + zv^2 - d zvv]], d = p_w - D(u, v) (this needs the second
  derivatives); where H is not positive definite the Gauss-Newton matrix (d = 0)
  is used instead;
- backtracking: the step is halved until f does not increase;
- stop test (paper eq. 2.17, per point): the squared change of the foot point
  between iterations is at most ``tol_mm**2``, the residual |F| is at round-off
  level, and H is positive definite (a true nearest point, not a saddle of f).

Points that do not meet the stop test within ``max_iterations`` (or that stall) are
returned with ``converged = False``: they are flagged, not silently wrong. See
``docs/math-surfaces.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.errors import InputError
from mppf.geometry.surface import Surface
from mppf.geometry.surface_math import unit_normals
from mppf.core.transform import apply_tf, as_points, tf_from_list
from mppf.core.validate import check_number, check_positive

RESIDUAL_TOL_REL = 1e-11
"""|F| must be below this times (1 mm + distance) to count as converged."""
MAX_HALVINGS = 30


@dataclass(frozen=True, eq=False)
class FootPoints:
    """Foot points of points on a surface, in the surface's local frame.

    Attributes
    ----------
    uv : (n, 2) float, mm
        Parameters of the foot points.
    xyz : (n, 3) float, mm
        Foot points (u, v, D(u, v)).
    distance_mm : (n,) float
        Signed normal distance, positive on the side of the surface normal (+w).
    converged : (n,) bool
        False where the iteration did not meet the stop test (result unreliable).
    iterations : int
        Newton iterations done (the slowest point).
    residual_mm : (n,) float
        |(F1, F2)| of eq. (2.11) at the result.
    mean_sq_change_mm2 : float
        Eq. (2.17): mean squared change of the foot points in the last iteration.
    """

    uv: np.ndarray
    xyz: np.ndarray
    distance_mm: np.ndarray
    converged: np.ndarray
    iterations: int
    residual_mm: np.ndarray
    mean_sq_change_mm2: float

    @property
    def n_failed(self) -> int:
        """Number of points that did not converge."""
        return int(np.count_nonzero(~self.converged))


def _objective(x, y, w, u, v, z):
    """f = |p - r|^2 / 2 for p = (x, y, w) and r = (u, v, z)."""
    return 0.5 * ((x - u) ** 2 + (y - v) ** 2 + (w - z) ** 2)


def _hessian(dw, zu, zv, zuu, zuv, zvv):
    """Hessian of f (Newton) with the Gauss-Newton matrix where it is not positive definite."""
    h11 = 1.0 + zu * zu - dw * zuu
    h12 = zu * zv - dw * zuv
    h22 = 1.0 + zv * zv - dw * zvv
    det = h11 * h22 - h12 * h12
    pd = (h11 > 0) & (det > 1e-12 * h11 * h22)
    gn11, gn12, gn22 = 1.0 + zu * zu, zu * zv, 1.0 + zv * zv
    return np.where(pd, h11, gn11), np.where(pd, h12, gn12), np.where(pd, h22, gn22), pd


def _residual(x, y, w, u, v, z, zu, zv):
    """(F1, F2) of the corrected eq. (2.11): (p - r) . (1, 0, zu) and (p - r) . (0, 1, zv)."""
    dw = w - z
    return (x - u) + dw * zu, (y - v) + dw * zv


def foot_points(surface: Surface, points, *, tf=None, tol_mm: float = 1e-9,
                max_iterations: int = 50) -> FootPoints:
    """Foot points of ``points`` on ``surface`` by damped Newton-Raphson (eq. 2.11-2.17).

    Parameters
    ----------
    surface : Surface
        z = D(u, v) in its local frame.
    points : (n, 3) float, mm
        Points in the surface's local frame, or in any frame when ``tf`` is given.
    tf : (4, 4) float, optional
        Transform applied to ``points`` first (the paper's T r*).
    tol_mm : float
        Stop when a foot point moves less than this between iterations (eq. 2.17).
    max_iterations : int

    Returns
    -------
    FootPoints

    Raises
    ------
    InputError
        Bad shapes, a bad transform, or non-positive tolerance / iteration count.
    """
    p, max_iterations = _checked(points, tf, tol_mm, max_iterations)
    x, y, w = p[:, 0], p[:, 1], p[:, 2]
    u, v = x.copy(), y.copy()
    deriv = [np.asarray(a, dtype=float) for a in surface.derivatives(u, v)]
    converged = np.zeros(len(p), dtype=bool)
    active = np.arange(len(p))
    iterations = 0
    mean_sq_change = 0.0
    while active.size and iterations < max_iterations:
        iterations += 1
        xyw, ua, va = (x[active], y[active], w[active]), u[active], v[active]
        old = [a[active] for a in deriv]
        # damped Newton step, halved where f would increase
        new_u, new_v, new = _damped_step(surface, xyw, ua, va, old)
        change_sq = (new_u - ua) ** 2 + (new_v - va) ** 2 + (new[0] - old[0]) ** 2
        mean_sq_change = float(np.mean(change_sq))  # eq. (2.17) over the active points
        u[active], v[active] = new_u, new_v
        for full, part in zip(deriv, new):
            full[active] = part
        # stop test at the new position
        done = (change_sq <= tol_mm * tol_mm) & _at_foot(xyw, new_u, new_v, new)
        stalled = (change_sq == 0.0) & ~done
        converged[active[done]] = True
        active = active[~done & ~stalled]
    z, zu, zv = deriv[0], deriv[1], deriv[2]
    xyz = np.column_stack([u, v, z])
    r1, r2 = _residual(x, y, w, u, v, z, zu, zv)
    distance = np.einsum("ij,ij->i", p - xyz, unit_normals(zu, zv))
    return FootPoints(uv=np.column_stack([u, v]), xyz=xyz, distance_mm=distance, converged=converged,
                      iterations=iterations, residual_mm=np.hypot(r1, r2), mean_sq_change_mm2=mean_sq_change)


def _checked(points, tf, tol_mm: float, max_iterations: int) -> tuple[np.ndarray, int]:
    """The points in the surface's frame, (n, 3) float mm, and the iteration limit, checked."""
    p = as_points(points)
    if tf is not None:
        p = apply_tf(tf_from_list(tf, name="tf"), p)
    if not np.all(np.isfinite(p)):
        raise InputError("points contain NaN or infinite values", hint="remove invalid points first")
    check_positive("tol_mm", tol_mm, unit="mm")
    return p, check_number("max_iterations", max_iterations, low=1, integer=True)


def _damped_step(surface: Surface, xyw, ua, va, old):
    """One damped Newton step of the active points.

    Parameters
    ----------
    surface : Surface
    xyw : tuple of three (m,) float, mm
        The active points.
    ua, va : (m,) float, mm
        Their foot-point parameters now.
    old : list of six (m,) float
        z, zu, zv, zuu, zuv, zvv at (ua, va).

    Returns
    -------
    new_u, new_v : (m,) float, mm
        The parameters after the step (the old ones where the line search failed).
    new : list of six (m,) float
        The derivatives there.
    """
    xa, ya, wa = xyw
    z, zu, zv, zuu, zuv, zvv = old
    f1, f2 = _residual(xa, ya, wa, ua, va, z, zu, zv)
    h11, h12, h22, _ = _hessian(wa - z, zu, zv, zuu, zuv, zvv)
    det = h11 * h22 - h12 * h12
    step_u = (h22 * f1 - h12 * f2) / det
    step_v = (h11 * f2 - h12 * f1) / det
    f_old = _objective(xa, ya, wa, ua, va, z)
    # round-off of f: distance times the coordinate round-off (about 1e-14 relative)
    f_limit = f_old + 1e-14 * (1.0 + np.abs(xa) + np.abs(ya) + np.abs(wa)) * (1.0 + np.sqrt(2.0 * f_old))
    new_u, new_v, new, worse = _line_search(surface, xyw, (ua, va), (step_u, step_v), f_limit)
    # points whose line search failed keep their old position
    if worse.any():
        new_u[worse], new_v[worse] = ua[worse], va[worse]
        for full, before in zip(new, old):
            full[worse] = before[worse]
    return new_u, new_v, new


def _line_search(surface: Surface, xyw, uv, step, f_limit):
    """Backtracking: halve the step (up to :data:`MAX_HALVINGS` times) where f would exceed ``f_limit``.

    Returns the parameters tried last, (m,) float mm each, the six derivatives there, and
    where f is still above ``f_limit`` ((m,) bool).
    """
    xa, ya, wa = xyw
    (ua, va), (step_u, step_v) = uv, step
    alpha = np.ones_like(ua)
    new_u, new_v = ua + step_u, va + step_v
    new = [np.asarray(a, dtype=float) for a in surface.derivatives(new_u, new_v)]
    worse = ~(_objective(xa, ya, wa, new_u, new_v, new[0]) <= f_limit)
    for _ in range(MAX_HALVINGS):
        if not worse.any():
            break
        idx = np.flatnonzero(worse)
        alpha[idx] *= 0.5
        new_u[idx] = ua[idx] + alpha[idx] * step_u[idx]
        new_v[idx] = va[idx] + alpha[idx] * step_v[idx]
        trial = surface.derivatives(new_u[idx], new_v[idx])
        for full, part in zip(new, trial):
            full[idx] = part
        still = ~(_objective(xa[idx], ya[idx], wa[idx], new_u[idx], new_v[idx], new[0][idx]) <= f_limit[idx])
        worse[idx] = still
    return new_u, new_v, new, worse


def _at_foot(xyw, new_u, new_v, new) -> np.ndarray:
    """(m,) bool: the residual |F| is at round-off level and H is positive definite (a true foot point)."""
    xa, ya, wa = xyw
    nz, nzu, nzv, nzuu, nzuv, nzvv = new
    r1, r2 = _residual(xa, ya, wa, new_u, new_v, nz, nzu, nzv)
    dist = np.sqrt(2.0 * _objective(xa, ya, wa, new_u, new_v, nz))
    small = np.hypot(r1, r2) <= RESIDUAL_TOL_REL * (1.0 + dist)
    *_, pd = _hessian(wa - nz, nzu, nzv, nzuu, nzuv, nzvv)
    return small & pd


def project_vertical(surface: Surface, u, v) -> np.ndarray:
    """Points (u, v, D(u, v)) straight above/below the given (u, v), shape (n, 3), mm."""
    u_arr, v_arr = np.broadcast_arrays(np.asarray(u, dtype=float).ravel(), np.asarray(v, dtype=float).ravel())
    return np.column_stack([u_arr, v_arr, surface.evaluate(u_arr, v_arr)])
