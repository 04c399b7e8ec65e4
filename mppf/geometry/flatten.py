"""The flat layout of a triangulated plate with the least change of its edge lengths.

A start (the projection on the best-fit plane for a shallow plate, else the
least-squares conformal map), then Gauss-Newton steps on ``sum_edges (|f_i - f_j| -
L_ij)^2`` with the analytic sparse Jacobian, a sparse direct solve and a fold guard
(see ``docs/unfold.md``).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from mppf.core.polygon import convex_outline_index
from mppf.geometry.mesh import edge_lengths, signed_areas_2d, triangles_in_own_plane, unique_edges

SHALLOW_EDGE_STRAIN = 0.01
"""A plate whose (u, v) projection shortens no edge by more than this fraction starts
the solver from that projection instead of the conformal map."""

FOLD_GUARD_AREA = 0.5
"""The fold guard acts on flat triangles whose area is below this fraction of the true area."""


def start_layout(pts, tri, uv, edges, lengths_mm) -> np.ndarray:
    """Starting layout (n, 2): the (u, v) projection when it already keeps every edge
    length within :data:`SHALLOW_EDGE_STRAIN` (a shallow plate: no factorization
    needed), otherwise the least-squares conformal map."""
    projected = edge_lengths(uv, edges)
    if np.all(projected >= (1.0 - SHALLOW_EDGE_STRAIN) * lengths_mm):
        return uv.copy()
    return _lscm(pts, tri, uv)


def _lscm(pts: np.ndarray, tri: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Least-squares conformal map (Levy et al. 2002) of the mesh, scaled to its edges.

    Each triangle is laid in its own plane, counter-clockwise as seen from +n; the
    anti-conformal part ``b`` of the linear map ``U = a z + b conj(z)`` from that
    triangle to the plane is driven to zero in the least-squares sense, with the two
    points farthest apart in (u, v) pinned. A mirror image has ``a = 0``: never a minimum.

    Returns
    -------
    (n, 2) float, mm
    """
    n = pts.shape[0]
    len12, x3, y3 = triangles_in_own_plane(pts, tri)
    w = np.stack([np.zeros_like(len12) + 0j, len12 + 0j, x3 + 1j * y3], axis=1)
    coef = np.stack([w[:, 2] - w[:, 1], w[:, 0] - w[:, 2], w[:, 1] - w[:, 0]], axis=1)
    coef /= np.sqrt(np.maximum(0.5 * len12 * y3, 1e-300))[:, None]
    m = tri.shape[0]
    rows = np.repeat(np.arange(m), 3)
    xs, ys = 2 * tri.ravel(), 2 * tri.ravel() + 1
    pr, pi = coef.real.ravel(), coef.imag.ravel()
    # rows: real part sum(p x - q y), imaginary part sum(q x + p y); unknowns x0, y0, x1, ...
    a = sp.coo_matrix(
        (np.concatenate([pr, -pi, pi, pr]),
         (np.concatenate([rows, rows, rows + m, rows + m]), np.concatenate([xs, ys, xs, ys]))),
        shape=(2 * m, 2 * n),
    ).tocsc()
    # pin the two points farthest apart in (u, v) at their (u, v) positions
    hull = convex_outline_index(uv) if n > 3 else np.arange(n)
    d = np.linalg.norm(uv[hull][:, None] - uv[hull][None], axis=2)
    i, j = np.unravel_index(np.argmax(d), d.shape)
    pins = np.array([hull[i], hull[j]])
    pinned = np.concatenate([2 * pins, 2 * pins + 1])
    values = np.concatenate([uv[pins, 0], uv[pins, 1]])
    free = np.setdiff1d(np.arange(2 * n), pinned)
    a_free = a[:, free]
    solution = np.empty(2 * n)
    solution[pinned] = values
    solution[free] = _factor(a_free.T @ a_free).solve(a_free.T @ -(a[:, pinned] @ values))
    return _scaled_to(solution.reshape(n, 2), pts, tri)


def _factor(normal):
    """Sparse LU of a symmetric positive (semi-)definite normal matrix."""
    return splu(sp.csc_matrix(normal), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                options={"SymmetricMode": True})


def _scaled_to(flat: np.ndarray, pts: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Scale a flat layout so that its edge lengths best match the 3D ones."""
    edges, _ = unique_edges(tri)
    lf, l3 = edge_lengths(flat, edges), edge_lengths(pts, edges)
    scale = float(lf @ l3) / max(float(lf @ lf), 1e-300)
    return flat * scale


class EdgeProblem:
    """Residuals and analytic sparse Jacobian of the flattening energy.

    Residuals: ``|f_i - f_j| - L_ij`` for every edge, then for every triangle the fold
    guard ``max(0, FOLD_GUARD_AREA * A - a) / sqrt(A)`` (A true area, a flat signed area),
    which is zero for every healthy triangle and grows as a triangle collapses or flips.
    Unknowns are interleaved: ``z = (x0, y0, x1, y1, ...)``.
    """

    def __init__(self, edges, lengths_mm, tri, areas_mm2, n_points):
        self.edges, self.lengths_mm, self.tri, self.n = edges, lengths_mm, tri, n_points
        self.sqrt_area = np.sqrt(np.maximum(areas_mm2, 1e-300))
        self.guard_area = FOLD_GUARD_AREA * areas_mm2
        k, m = edges.shape[0], tri.shape[0]
        i, j = edges[:, 0], edges[:, 1]
        edge_cols = np.stack([2 * i, 2 * i + 1, 2 * j, 2 * j + 1], axis=1).ravel()
        guard_cols = np.stack([2 * tri, 2 * tri + 1], axis=2).reshape(m, 6).ravel()
        self.rows = np.concatenate([np.repeat(np.arange(k), 4), k + np.repeat(np.arange(m), 6)])
        self.cols = np.concatenate([edge_cols, guard_cols])
        self.shape = (k + m, 2 * n_points)

    def residuals(self, z):
        """Residuals (k + m,): edge length errors (mm), then the fold guard of each triangle."""
        flat = z.reshape(-1, 2)
        length = edge_lengths(flat, self.edges)
        area = signed_areas_2d(flat, self.tri)
        return np.concatenate([length - self.lengths_mm,
                               np.maximum(0.0, self.guard_area - area) / self.sqrt_area])

    def jacobian(self, z):
        """Sparse Jacobian (k + m, 2 n) of :meth:`residuals` at ``z``."""
        flat = z.reshape(-1, 2)
        i, j = self.edges[:, 0], self.edges[:, 1]
        diff = flat[i] - flat[j]
        unit = diff / np.maximum(np.linalg.norm(diff, axis=1), 1e-12)[:, None]
        edge_vals = np.concatenate([unit, -unit], axis=1).ravel()
        a, b, c = flat[self.tri[:, 0]], flat[self.tri[:, 1]], flat[self.tri[:, 2]]
        area = signed_areas_2d(flat, self.tri)
        active = (self.guard_area - area > 0) / self.sqrt_area
        # d(area) / d(xa, ya, xb, yb, xc, yc); the guard residual is -active * d(area)
        d_area = 0.5 * np.stack([b[:, 1] - c[:, 1], c[:, 0] - b[:, 0], c[:, 1] - a[:, 1],
                                 a[:, 0] - c[:, 0], a[:, 1] - b[:, 1], b[:, 0] - a[:, 0]], axis=1)
        guard_vals = (-active[:, None] * d_area).ravel()
        return sp.csr_matrix((np.concatenate([edge_vals, guard_vals]), (self.rows, self.cols)),
                             shape=self.shape)


def solve(start: np.ndarray, problem: EdgeProblem, *, max_iterations: int = 100,
          tol_mm: float = 1e-9) -> tuple[np.ndarray, int, float]:
    """Minimise ``0.5 * |r|^2`` by Gauss-Newton steps with a lagged sparse factorization.

    The normal matrix ``J^T J`` (plus a tiny multiple of its mean diagonal, which
    removes the free rigid motion of the plane) is factored at the start and again
    whenever the steps stop shrinking fast; in between, its factors are reused
    (chord iterations), each step followed by a backtracking line search.

    Returns
    -------
    flat : (n, 2) float, mm
    iterations : int
        Gauss-Newton steps taken.
    cost : float, mm^2
    """
    z = start.ravel().copy()
    r = problem.residuals(z)
    cost = 0.5 * float(r @ r)
    scale_mm = float(np.median(problem.lengths_mm))
    lu, last_step, iterations = None, np.inf, 0
    while iterations < max_iterations:
        jac = problem.jacobian(z)
        gradient = jac.T @ r
        if lu is None:
            normal = (jac.T @ jac).tocsc()
            damping = 1e-9 * float(normal.diagonal().mean())
            lu = _factor(normal + damping * sp.identity(normal.shape[0], format="csc"))
            fresh = True
        step = -lu.solve(gradient)
        t, accepted = 1.0, False
        for _ in range(30):
            trial = z + t * step
            r_trial = problem.residuals(trial)
            cost_trial = 0.5 * float(r_trial @ r_trial)
            if cost_trial <= cost:
                accepted = True
                break
            t *= 0.5
        iterations += 1
        if not accepted:
            if fresh:
                break  # no descent even with fresh factors: at the minimum
            lu = None
            continue
        size = float(np.abs(t * step).max())
        z, r, cost_old, cost = trial, r_trial, cost, cost_trial
        if size <= tol_mm * max(scale_mm, 1.0) or cost_old - cost <= 1e-15 * cost_old:
            break
        # reuse the factors while the steps shrink at least fourfold
        if size > 0.25 * last_step or t < 1.0:
            lu = None
        fresh = False
        last_step = size
    return z.reshape(-1, 2), iterations, cost
