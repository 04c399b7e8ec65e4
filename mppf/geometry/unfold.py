"""Unfold a curved plate into its flat shape, with the in-plane strain it costs.

The flat (developed) plate is what the cutting machine cuts and the press forms. The
method (see ``docs/unfold.md``):

1. find the plate's own frame (:func:`mppf.geometry.frame.fit_frame`) and refuse plates that
   fold over in it (:func:`mppf.geometry.frame.check_height_field`);
2. triangulate: the given mesh faces, or a Delaunay triangulation of the (u, v)
   projection with the sliver triangles of a non-convex outline removed;
3. start from the projection on the best-fit plane when it keeps every edge within
   1 % (a shallow plate), otherwise from the least-squares conformal map (LSCM, a
   sparse linear solve, exact up to scale for developable plates); both preserve
   orientation;
4. minimise ``sum_edges (|f_i - f_j| - L_ij)^2`` (L_ij the 3D edge lengths) by
   Gauss-Newton steps with the analytic sparse Jacobian and a sparse direct solve
   (scipy.sparse.linalg.splu), plus a fold guard that is zero unless a flat triangle
   shrinks below half its true area;
5. measure the strain of every triangle from its deformation gradient, and place the
   flat plate at z = 0, its minimum-area bounding rectangle centred at the origin,
   longer side along x, turned as close as possible to the design's (u, v) view.

The flat points keep the order and count of the input, so design and flat are a set of
known correspondences. Pure: arrays in, arrays out.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu
from scipy.spatial import Delaunay

from mppf.core.errors import GeometryError, InputError
from mppf.geometry.frame import LocalFrame, check_height_field, fit_frame
from mppf.core.polygon import convex_outline, convex_outline_index
from mppf.core.rigid import fit_rigid
from mppf.geometry.io import check_plate

STRAIN_LIMIT_PCT = 1.5
"""Default in-plane strain (percent) above which press forming needs a warning."""

DEVELOPABLE_PCT = 0.1
"""Maximum strain (percent) below which a plate counts as (practically) developable."""

SLIVER_QUALITY = 0.05
"""Boundary triangles of a Delaunay triangulation with quality 4*sqrt(3)*A/sum(l^2)
below this (1 = equilateral, 0 = degenerate) are slivers of the convex hull."""

SLIVER_EDGE_FACTOR = 2.5
"""Boundary triangles with an edge longer than this times the median edge are removed too."""

SHALLOW_EDGE_STRAIN = 0.01
"""A plate whose (u, v) projection shortens no edge by more than this fraction starts
the solver from that projection instead of the conformal map."""

FOLD_GUARD_AREA = 0.5
"""The fold guard acts on flat triangles whose area is below this fraction of the true area."""


@dataclass(frozen=True, eq=False)
class Unfolding:
    """The flat shape of a plate and the strain it costs.

    Attributes
    ----------
    flat : (n, 3) float, mm
        Flat points in the input order, z = 0; the minimum-area bounding rectangle is
        centred at the origin with its longer side along x.
    strain_pct : (n,) float, percent
        In-plane strain per point: area-weighted mean over the incident triangles of
        the largest principal strain magnitude ``max(|s1 - 1|, |s2 - 1|)``.
    triangle_strain_pct : (m, 2) float, percent
        Signed principal strains (smaller, larger) of each triangle (+ stretched,
        - compressed when the curved plate is laid flat).
    faces : (m, 3) int
        Triangles used, wound counter-clockwise seen from the design's +n side.
    rms_strain_pct, max_strain_pct : float
        RMS and maximum of ``strain_pct``.
    area_change_pct : float
        Flat area minus curved (triangulated) area, in percent of the curved area.
    outline_length_change_pct : float
        Flat outline length minus curved outline length, percent of the curved one.
    developable : bool
        ``max_strain_pct`` below :data:`DEVELOPABLE_PCT`.
    worst_point : int
        Index of the point with the largest strain.
    worst_uv_mm : (2,) float
        That point in the plate's own frame (u, v), mm from the centroid.
    worst_region : str
        Where it is, e.g. ``"the +u/-v corner"``.
    warnings : tuple of str
    frame : LocalFrame
        The plate's own frame (u, v, n) used.
    tf_flat_design : (4, 4) float
        Best rigid fit mapping design points onto the flat points (for orientation only;
        the flat plate is not a rigid image of the curved one).
    strain_limit_pct : float
    iterations : int
        Gauss-Newton steps taken.
    cost : float, mm^2
        Final ``0.5 * sum(residual^2)``.
    """

    flat: np.ndarray
    strain_pct: np.ndarray
    triangle_strain_pct: np.ndarray
    faces: np.ndarray
    rms_strain_pct: float
    max_strain_pct: float
    area_change_pct: float
    outline_length_change_pct: float
    developable: bool
    worst_point: int
    worst_uv_mm: np.ndarray
    worst_region: str
    frame: LocalFrame
    tf_flat_design: np.ndarray
    strain_limit_pct: float
    iterations: int
    cost: float
    warnings: tuple[str, ...] = field(default_factory=tuple)

    @property
    def n_points(self) -> int:
        """Number of points."""
        return int(self.flat.shape[0])

    def to_dict(self) -> dict:
        """The report as plain values (for JSON)."""
        return {
            "rms_strain_pct": self.rms_strain_pct,
            "max_strain_pct": self.max_strain_pct,
            "area_change_pct": self.area_change_pct,
            "outline_length_change_pct": self.outline_length_change_pct,
            "n_points": self.n_points,
            "n_triangles": int(self.faces.shape[0]),
            "developable": self.developable,
            "strain_limit_pct": self.strain_limit_pct,
            "worst_point": self.worst_point,
            "worst_uv_mm": self.worst_uv_mm.tolist(),
            "worst_region": self.worst_region,
            "flat_size_mm": np.ptp(self.flat[:, :2], axis=0).tolist(),
            "iterations": self.iterations,
            "cost_mm2": self.cost,
            "warnings": list(self.warnings),
        }


def unfold(points, faces=None, *, strain_limit_pct: float = STRAIN_LIMIT_PCT) -> Unfolding:
    """Flatten a curved plate with the least change of its edge lengths.

    Parameters
    ----------
    points : (n, 3) float, mm
        The curved plate in any coordinates (a grid, a point cloud or mesh vertices).
    faces : (m, 3) int, optional
        Mesh triangles; without them the (u, v) projection is triangulated.
    strain_limit_pct : float
        Strain (percent) above which the result carries a warning.

    Returns
    -------
    Unfolding

    Raises
    ------
    GeometryError
        Fewer than 3 non-collinear points, a plate that folds over in its own frame,
        points that belong to no triangle, a flattening that folds.
    InputError
        Bad ``faces`` or ``strain_limit_pct``.
    """
    pts = check_plate(points, 3, "the design")
    if not (np.isfinite(strain_limit_pct) and strain_limit_pct > 0):
        raise InputError(f"the strain limit must be a positive percentage, got {strain_limit_pct}",
                         hint="give e.g. 1.5 (percent)")
    # 1. the plate's own frame; refuse plates that are not one layer in it
    frame = fit_frame(pts)
    tri = None if faces is None else _check_faces(faces, pts.shape[0])
    check_height_field(frame, pts, tri)
    uv = frame.to_local(pts)[:, :2]
    # 2. triangles, wound counter-clockwise seen from +n
    tri = _triangulate(uv, pts) if tri is None else _wind_ccw(uv, tri)
    _check_all_used(tri, pts.shape[0])
    edges, boundary = _edges(tri)
    lengths_mm = np.linalg.norm(pts[edges[:, 0]] - pts[edges[:, 1]], axis=1)
    # 3. start: the projection on the best-fit plane for a shallow plate, else the LSCM
    start = _start(pts, tri, uv, edges, lengths_mm)
    # 4. least-squares edge lengths, with a fold guard
    problem = _EdgeProblem(edges, lengths_mm, tri, _triangle_areas(pts, tri), pts.shape[0])
    flat2, iterations, cost = _solve(start, problem)
    # 5. strain, placement, report
    return _report(pts, tri, flat2, uv, frame, edges, boundary, lengths_mm,
                   strain_limit_pct, iterations, cost)


# --------------------------------------------------------------------- triangles


def _check_faces(faces, n_points: int) -> np.ndarray:
    tri = np.asarray(faces)
    if tri.ndim != 2 or tri.shape[1] != 3 or tri.shape[0] == 0:
        raise InputError(f"faces must have shape (m, 3) with m >= 1, got {tri.shape}",
                         hint="give triangles as rows of three point indices")
    if not np.issubdtype(tri.dtype, np.integer):
        raise InputError(f"faces must be integer point indices, got {tri.dtype}")
    tri = tri.astype(np.int64)
    if tri.min() < 0 or tri.max() >= n_points:
        raise InputError(f"faces refer to point {int(tri.max()) if tri.max() >= n_points else int(tri.min())},"
                         f" but there are {n_points} points", hint="the mesh is broken; re-export it")
    degenerate = (tri[:, 0] == tri[:, 1]) | (tri[:, 1] == tri[:, 2]) | (tri[:, 0] == tri[:, 2])
    return tri[~degenerate]


def _triangle_areas(pts: np.ndarray, tri: np.ndarray) -> np.ndarray:
    a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


def _signed_areas_2d(xy: np.ndarray, tri: np.ndarray) -> np.ndarray:
    a, b, c = xy[tri[:, 0]], xy[tri[:, 1]], xy[tri[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))


def _wind_ccw(uv: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Reverse a consistently wound mesh when most triangles run clockwise in (u, v)."""
    if np.sum(_signed_areas_2d(uv, tri)) < 0:
        return tri[:, ::-1].copy()
    return tri


def _triangulate(uv: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Delaunay triangles of the (u, v) projection without the convex hull's slivers.

    Boundary triangles that are slivers (quality below :data:`SLIVER_QUALITY`) or have
    an edge longer than :data:`SLIVER_EDGE_FACTOR` times the median edge are peeled off
    repeatedly, as long as their points stay in other triangles.
    """
    tri = Delaunay(uv).simplices.astype(np.int64)
    area_uv = _signed_areas_2d(uv, tri)
    tri[area_uv < 0] = tri[area_uv < 0][:, ::-1]  # every triangle counter-clockwise
    tri = tri[np.abs(area_uv) > 1e-12 * float(np.ptp(uv, axis=0).max()) ** 2]  # no flat ones
    while True:
        a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
        sq = np.column_stack([np.sum((b - a) ** 2, 1), np.sum((c - b) ** 2, 1), np.sum((a - c) ** 2, 1)])
        area = _triangle_areas(pts, tri)
        quality = 4.0 * np.sqrt(3.0) * area / np.maximum(sq.sum(axis=1), 1e-300)
        longest = np.sqrt(sq.max(axis=1))
        median = np.median(np.sqrt(sq))
        bad = (quality < SLIVER_QUALITY) | (longest > SLIVER_EDGE_FACTOR * median)
        on_boundary = _on_boundary(tri)
        candidates = np.flatnonzero(bad & on_boundary)
        if candidates.size == 0:
            return tri
        # peel only triangles whose corners all stay in some other triangle
        uses = np.bincount(tri.ravel(), minlength=pts.shape[0])
        left = uses - np.bincount(tri[candidates].ravel(), minlength=pts.shape[0])
        removable = candidates[np.all(left[tri[candidates]] > 0, axis=1)]
        if removable.size == 0:
            return tri
        tri = np.delete(tri, removable, axis=0)


def _edge_keys(tri: np.ndarray) -> np.ndarray:
    """One integer key per triangle side (3m,): sides 01, 12, 20 of every triangle."""
    pairs = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    pairs.sort(axis=1)
    return pairs[:, 0] * (int(tri.max()) + 1) + pairs[:, 1]


def _edges(tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique edges (k, 2) of the triangles and a mask of those on the boundary."""
    width = int(tri.max()) + 1
    keys, counts = np.unique(_edge_keys(tri), return_counts=True)
    return np.column_stack([keys // width, keys % width]), counts == 1


def boundary_edges(faces) -> np.ndarray:
    """Sides (k, 2) of a triangulation that belong to one triangle only: its outline.

    Parameters
    ----------
    faces : (m, 3) int

    Returns
    -------
    (k, 2) int
    """
    edges, boundary = _edges(np.asarray(faces, dtype=np.int64))
    return edges[boundary]


def _on_boundary(tri: np.ndarray) -> np.ndarray:
    """Mask of triangles with at least one side that no other triangle shares."""
    _, inverse, counts = np.unique(_edge_keys(tri), return_inverse=True, return_counts=True)
    return (counts[inverse] == 1).reshape(3, -1).any(axis=0)


def _check_all_used(tri: np.ndarray, n_points: int) -> None:
    unused = np.flatnonzero(np.bincount(tri.ravel(), minlength=n_points) == 0)
    if unused.size:
        raise GeometryError(
            f"{unused.size} point(s) belong to no triangle (first: point {int(unused[0])}); "
            "duplicate points or mesh vertices without faces cannot be unfolded",
            hint="remove duplicate or loose points from the design",
        )


# --------------------------------------------------------------------- solving


def _triangles_in_own_plane(pts: np.ndarray, tri: np.ndarray):
    """Each triangle laid in its own plane: corners (0, 0), (len12, 0), (x3, y3), y3 > 0.

    Returns
    -------
    len12, x3, y3 : (m,) float, mm
        The triangle counter-clockwise in its plane, as seen from the side its
        winding makes positive (+n for the triangles built here).
    """
    p1, p2, p3 = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    e1 = p2 - p1
    len12 = np.linalg.norm(e1, axis=1)
    e1 = e1 / len12[:, None]
    d3 = p3 - p1
    x3 = np.sum(d3 * e1, axis=1)
    y3 = np.linalg.norm(d3 - x3[:, None] * e1, axis=1)
    return len12, x3, y3


def _start(pts, tri, uv, edges, lengths_mm) -> np.ndarray:
    """Starting layout (n, 2): the (u, v) projection when it already keeps every edge
    length within :data:`SHALLOW_EDGE_STRAIN` (a shallow plate: no factorization
    needed), otherwise the least-squares conformal map."""
    projected = np.linalg.norm(uv[edges[:, 0]] - uv[edges[:, 1]], axis=1)
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
    len12, x3, y3 = _triangles_in_own_plane(pts, tri)
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
    edges, _ = _edges(tri)
    lf = np.linalg.norm(flat[edges[:, 0]] - flat[edges[:, 1]], axis=1)
    l3 = np.linalg.norm(pts[edges[:, 0]] - pts[edges[:, 1]], axis=1)
    scale = float(lf @ l3) / max(float(lf @ lf), 1e-300)
    return flat * scale


class _EdgeProblem:
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
        flat = z.reshape(-1, 2)
        i, j = self.edges[:, 0], self.edges[:, 1]
        length = np.linalg.norm(flat[i] - flat[j], axis=1)
        area = _signed_areas_2d(flat, self.tri)
        return np.concatenate([length - self.lengths_mm,
                               np.maximum(0.0, self.guard_area - area) / self.sqrt_area])

    def jacobian(self, z):
        flat = z.reshape(-1, 2)
        i, j = self.edges[:, 0], self.edges[:, 1]
        diff = flat[i] - flat[j]
        unit = diff / np.maximum(np.linalg.norm(diff, axis=1), 1e-12)[:, None]
        edge_vals = np.concatenate([unit, -unit], axis=1).ravel()
        a, b, c = flat[self.tri[:, 0]], flat[self.tri[:, 1]], flat[self.tri[:, 2]]
        area = _signed_areas_2d(flat, self.tri)
        active = (self.guard_area - area > 0) / self.sqrt_area
        # d(area) / d(xa, ya, xb, yb, xc, yc); the guard residual is -active * d(area)
        d_area = 0.5 * np.stack([b[:, 1] - c[:, 1], c[:, 0] - b[:, 0], c[:, 1] - a[:, 1],
                                 a[:, 0] - c[:, 0], a[:, 1] - b[:, 1], b[:, 0] - a[:, 0]], axis=1)
        guard_vals = (-active[:, None] * d_area).ravel()
        return sp.csr_matrix((np.concatenate([edge_vals, guard_vals]), (self.rows, self.cols)),
                             shape=self.shape)


def _solve(start: np.ndarray, problem: _EdgeProblem, *, max_iterations: int = 100,
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


# --------------------------------------------------------------------- report


def _principal_strains(pts: np.ndarray, tri: np.ndarray, flat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Principal stretches of each triangle's deformation gradient curved -> flat.

    Returns
    -------
    stretches : (m, 2) float
        Smaller and larger singular value of the 2x2 deformation gradient F.
    det : (m,) float
        det F (negative for a triangle flipped in the flat layout).
    """
    len12, x3, y3 = _triangles_in_own_plane(pts, tri)
    f1, f2, f3 = flat[tri[:, 0]], flat[tri[:, 1]], flat[tri[:, 2]]
    # F @ [[len12, x3], [0, y3]] = [f2 - f1, f3 - f1]
    g1, g2 = f2 - f1, f3 - f1
    a = g1[:, 0] / len12
    c = g1[:, 1] / len12
    b = (g2[:, 0] - a * x3) / y3
    d = (g2[:, 1] - c * x3) / y3
    # singular values of [[a, b], [c, d]]
    s_sum = np.hypot(a + d, c - b)
    s_dif = np.hypot(a - d, c + b)
    stretches = np.column_stack([0.5 * np.abs(s_sum - s_dif), 0.5 * (s_sum + s_dif)])
    return stretches, a * d - b * c


def _place(flat: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Rotate and shift a flat layout: minimum-area rectangle centred, long side on x.

    Of the rotations that do so, the one closest to the design's (u, v) view is taken.
    """
    hull = convex_outline(flat) if flat.shape[0] > 3 else flat
    sides = np.roll(hull, -1, axis=0) - hull
    angles = np.arctan2(sides[:, 1], sides[:, 0])
    best = None
    for angle in angles:
        rot = _rotation(-angle)
        ext = np.ptp(hull @ rot.T, axis=0)
        if best is None or ext[0] * ext[1] < best[0] - 1e-9 * best[0]:
            best = (ext[0] * ext[1], -angle if ext[0] >= ext[1] else -angle + np.pi / 2)
    base = best[1]
    # rotation taking the (u, v) view onto the flat layout (2D Procrustes, no mirror)
    fc, uc = flat - flat.mean(axis=0), uv - uv.mean(axis=0)
    cross = np.sum(uc[:, 0] * fc[:, 1] - uc[:, 1] * fc[:, 0])
    dot = np.sum(uc * fc)
    view = np.arctan2(cross, dot)
    turn = min((base, base + np.pi), key=lambda t: abs(np.angle(np.exp(1j * (t + view)))))
    placed = flat @ _rotation(turn).T
    lo, hi = placed.min(axis=0), placed.max(axis=0)
    return placed - 0.5 * (lo + hi)


def _rotation(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def region_name(uv_mm: np.ndarray, point: int) -> str:
    """Name where ``point`` lies on the plate: a corner, an edge or the middle.

    The outer quarters of the (u, v) bounding box are the edges, where two meet a corner.

    Parameters
    ----------
    uv_mm : (n, 2) float
        The plate's points in its own frame.
    point : int

    Returns
    -------
    str
        e.g. ``"the +u/-v corner"``, ``"the -u edge"``, ``"the middle"``.
    """
    lo, hi = uv_mm.min(axis=0), uv_mm.max(axis=0)
    where = (uv_mm[point] - lo) / np.maximum(hi - lo, 1e-300)
    parts = []
    for name, t in zip("uv", where):
        if t < 0.25:
            parts.append(f"-{name}")
        elif t > 0.75:
            parts.append(f"+{name}")
    if len(parts) == 2:
        return f"the {parts[0]}/{parts[1]} corner"
    if parts:
        return f"the {parts[0]} edge"
    return "the middle"


def _report(pts, tri, flat2, uv, frame, edges, boundary, lengths_mm, strain_limit_pct,
            iterations, cost) -> Unfolding:
    stretches, det = _principal_strains(pts, tri, flat2)
    flipped = np.flatnonzero(det <= 0)
    if flipped.size:
        centre = uv[tri[flipped[0]]].mean(axis=0) / 1000.0
        raise GeometryError(
            f"the flattening folds over: {flipped.size} of {tri.shape[0]} triangles come out "
            f"mirrored, first near u={centre[0]:+.2f} m, v={centre[1]:+.2f} m in the plate frame",
            hint="check the design for spikes, overlaps or a badly wound mesh",
        )
    if not np.all(np.isfinite(flat2)):
        raise GeometryError("the flattening did not converge (non-finite coordinates)",
                            hint="check the design for duplicate or stray points")
    # strain per triangle and per point
    principal = stretches - 1.0
    magnitude = np.abs(principal).max(axis=1)
    area = _triangle_areas(pts, tri)
    weight = np.bincount(tri.ravel(), weights=np.repeat(area, 3), minlength=pts.shape[0])
    per_point = np.bincount(tri.ravel(), weights=np.repeat(area * magnitude, 3),
                            minlength=pts.shape[0]) / weight
    strain_pct = 100.0 * per_point
    # area and outline
    flat_area = float(np.sum(_signed_areas_2d(flat2, tri)))
    curved_area = float(np.sum(area))
    e_b = edges[boundary]
    flat_outline = float(np.sum(np.linalg.norm(flat2[e_b[:, 0]] - flat2[e_b[:, 1]], axis=1)))
    curved_outline = float(np.sum(lengths_mm[boundary]))
    # placement
    placed = _place(flat2, uv)
    flat = np.column_stack([placed, np.zeros(pts.shape[0])])
    worst = int(np.argmax(strain_pct))
    worst_uv = uv[worst] - uv.mean(axis=0)
    region = region_name(uv, worst)
    max_strain = float(strain_pct[worst])
    warnings = []
    if max_strain > strain_limit_pct:
        warnings.append(
            f"in-plane strain {max_strain:.3g} % exceeds the limit {strain_limit_pct:g} % near {region} "
            f"(u={worst_uv[0] / 1000:+.2f} m, v={worst_uv[1] / 1000:+.2f} m in the plate frame, "
            f"x={flat[worst, 0] / 1000:+.2f} m, y={flat[worst, 1] / 1000:+.2f} m on the flat plate, point {worst}): "
            "press forming cannot take this without thinning or wrinkling; split the plate or add line heating"
        )
    return Unfolding(
        flat=flat,
        strain_pct=strain_pct,
        triangle_strain_pct=100.0 * principal,
        faces=tri,
        rms_strain_pct=float(np.sqrt(np.mean(strain_pct ** 2))),
        max_strain_pct=max_strain,
        area_change_pct=100.0 * (flat_area - curved_area) / curved_area,
        outline_length_change_pct=100.0 * (flat_outline - curved_outline) / curved_outline,
        developable=bool(max_strain < DEVELOPABLE_PCT),
        worst_point=worst,
        worst_uv_mm=worst_uv,
        worst_region=region,
        frame=frame,
        tf_flat_design=fit_rigid(pts, flat),
        strain_limit_pct=float(strain_limit_pct),
        iterations=iterations,
        cost=cost,
        warnings=tuple(warnings),
    )
