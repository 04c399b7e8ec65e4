"""Exact queries on a CAD model's trimmed faces: closest points, and where lines meet the surface.

Both are Newton iterations on the exact surfaces (:meth:`CadModel.derivatives`), in bulk
over the points of each face, started at the nearest seed point of the face; every face
near a point is tried and the answer must lie on the trimmed face (:meth:`CadModel.inside`).

* closest point: minimise ``|S(u, v) - p|^2`` (Newton with the full Hessian, Gauss-Newton
  where it is not positive definite), parameters kept in the face's domain;
* line ``o + t d``: solve ``E (S(u, v) - o) = 0`` with E the two unit vectors normal to d.

Results are :class:`SurfaceHits`; lengths in mm at full scale, like the model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.geometry.cad import CadModel, FaceTrees

NEWTON_STEPS = 40
CONVERGED_MM = 1e-7
"""A Newton step moving the surface point less than this ends the iteration."""

NEAR_SEEDS = 8.0
"""Seeds further than this many seed gaps from a point are not looked at first."""


@dataclass(frozen=True, eq=False)
class SurfaceHits:
    """Points found on a CAD model's trimmed faces, one per query.

    Attributes
    ----------
    points_mm : (n, 3) float
        The points on the surface (NaN where none was found).
    distance_mm : (n,) float
        Distance from the query point (closest points) or the line origin (lines); NaN where none.
    face : (n,) int
        Index into ``model.faces``, -1 where none.
    uv : (n, 2) float
        The face parameters (NaN where none).
    found : (n,) bool
    """

    points_mm: np.ndarray
    distance_mm: np.ndarray
    face: np.ndarray
    uv: np.ndarray
    found: np.ndarray


def closest_points(model: CadModel, points) -> SurfaceHits:
    """The closest point on the trimmed surfaces to each of ``points`` (n, 3) mm.

    Where the closest point of every nearby face lies outside its trim (a point beyond the
    model's edge), the nearest of those is returned with ``found`` False.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    on_face, anywhere = _Best(pts.shape[0]), _Best(pts.shape[0])
    for index, face, rows, start in _near_faces(model, pts):
        uv, ok = _newton_closest(model, face, pts[rows], start)
        xyz = model.evaluate(face, uv)
        dist = np.linalg.norm(xyz - pts[rows], axis=1)
        inside = model.inside(face, uv) & ok
        on_face.offer(rows[inside], xyz[inside], dist[inside], index, uv[inside], -dist[inside])
        anywhere.offer(rows, xyz, dist, index, uv, -dist)
    return on_face.hits(fallback=anywhere)


def intersect_lines(model: CadModel, origins, direction, *, seen_from=None) -> SurfaceHits:
    """Where lines ``origins + t direction`` meet the trimmed surfaces.

    Parameters
    ----------
    model : CadModel
    origins : (n, 3) float, mm
    direction : (3,) float
        One direction for every line.
    seen_from : (3,) float, optional
        Of several hits, keep the one furthest along this vector (the surface seen from
        that side); default: the hit nearest the origin.
    """
    pts = np.asarray(origins, dtype=float).reshape(-1, 3)
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    basis = _normal_basis(d)
    planar = pts @ basis.T
    hits = _Best(pts.shape[0])
    key = tuple(float(c) for c in np.round(d, 12))
    if key not in model.seed_trees_along:
        model.seed_trees_along[key] = _trees(model, lambda face: face.seed_mm @ basis.T)
    trees = model.seed_trees_along[key]
    for index, face in enumerate(model.faces):
        tree, spacing = trees[index]
        if tree is None:
            continue
        dist, seed = tree.query(planar, distance_upper_bound=2.0 * spacing)
        rows = np.flatnonzero(np.isfinite(dist))
        if rows.size:
            _line_face(model, index, pts[rows], np.broadcast_to(d, (rows.size, 3)), face.seed_uv[seed[rows]],
                       rows, hits, seen_from)
    return hits.hits()


def intersect_near(model: CadModel, origins, directions) -> SurfaceHits:
    """Where lines through points near the surface meet it: the hit nearest each origin.

    Parameters
    ----------
    origins : (n, 3) float, mm
        Points near the surface (within a few seed spacings).
    directions : (n, 3) float
        One direction per line.
    """
    pts = np.asarray(origins, dtype=float).reshape(-1, 3)
    d = np.asarray(directions, dtype=float).reshape(-1, 3)
    d = d / np.linalg.norm(d, axis=1)[:, None]
    hits = _Best(pts.shape[0])
    for index, _, rows, start in _near_faces(model, pts):
        _line_face(model, index, pts[rows], d[rows], start, rows, hits, None)
    return hits.hits()


# ---------------------------------------------------------------------- Newton


def _newton_closest(model: CadModel, face, pts: np.ndarray, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Foot points of ``pts`` on the untrimmed face: parameters (n, 2) and converged (n,) bool."""
    uv = uv.astype(float).copy()
    active = np.ones(pts.shape[0], dtype=bool)
    for _ in range(NEWTON_STEPS):
        rows = np.flatnonzero(active)
        if rows.size == 0:
            break
        r = model.evaluate(face, uv[rows]) - pts[rows]
        s_u, s_v, s_uu, s_vv, s_uv = model.derivatives(face, uv[rows])
        g = np.column_stack([_dot(s_u, r), _dot(s_v, r)])
        a, b, c = _dot(s_u, s_u), _dot(s_u, s_v), _dot(s_v, s_v)
        ha, hb, hc = a + _dot(s_uu, r), b + _dot(s_uv, r), c + _dot(s_vv, r)
        definite = (ha > 0) & (ha * hc - hb * hb > 1e-12 * (a * c + 1e-300))
        ha, hb, hc = np.where(definite, ha, a), np.where(definite, hb, b), np.where(definite, hc, c)
        step = _solve2(ha, hb, hb, hc, -g)
        moved = _move(face, uv, rows, step)
        active[rows] = np.linalg.norm(s_u * moved[:, :1] + s_v * moved[:, 1:], axis=1) > CONVERGED_MM
    return uv, ~active


def _line_face(model, index: int, origins, d, start, rows, hits: _Best, seen_from) -> None:
    """Newton for lines on face ``index`` of the model; keep the hits on the trimmed face in ``hits``."""
    face = model.faces[index]
    uv = start.astype(float).copy()
    e1 = _normal_basis_rows(d)
    active = np.ones(origins.shape[0], dtype=bool)
    for _ in range(NEWTON_STEPS):
        live = np.flatnonzero(active)
        if live.size == 0:
            break
        r = model.evaluate(face, uv[live]) - origins[live]
        s_u, s_v, *_ = model.derivatives(face, uv[live])
        b1, b2 = e1[0][live], e1[1][live]
        step = _solve2(_dot(b1, s_u), _dot(b1, s_v), _dot(b2, s_u), _dot(b2, s_v),
                       -np.column_stack([_dot(b1, r), _dot(b2, r)]))
        moved = _move(face, uv, live, step)
        active[live] = np.linalg.norm(s_u * moved[:, :1] + s_v * moved[:, 1:], axis=1) > CONVERGED_MM
    xyz = model.evaluate(face, uv)
    r = xyz - origins
    off = np.hypot(_dot(e1[0], r), _dot(e1[1], r))
    ok = ~active & (off < 1e-4 * max(model.seed_spacing_mm, 1.0)) & model.inside(face, uv)
    if seen_from is None:
        score = -np.linalg.norm(r, axis=1)
    else:
        score = xyz @ np.asarray(seen_from, dtype=float)
    hits.offer(rows[ok], xyz[ok], np.linalg.norm(r, axis=1)[ok], index, uv[ok], score[ok])


def _move(face, uv: np.ndarray, rows: np.ndarray, step: np.ndarray) -> np.ndarray:
    """Apply a Newton step kept inside the parameter domain; the step actually taken."""
    step = np.where(np.isfinite(step), step, 0.0)
    span = face.uv_high - face.uv_low
    step = np.clip(step, -0.25 * span, 0.25 * span)  # no jump across the whole face
    new = np.clip(uv[rows] + step, face.uv_low, face.uv_high)
    moved = new - uv[rows]
    uv[rows] = new
    return moved


# ---------------------------------------------------------------------- candidates


def _near_faces(model: CadModel, pts: np.ndarray):
    """For each face near some of ``pts``: (index, face, rows, starting parameters of those rows)."""
    if model.seed_trees_xyz is None:
        model.seed_trees_xyz = _trees(model, lambda face: face.seed_mm)
    trees = model.seed_trees_xyz
    reach = NEAR_SEEDS * max(spacing for _, spacing in trees)
    found = [(_query(tree, pts, reach), spacing) for tree, spacing in trees]
    nearest = np.min([dist for (dist, _), _ in found], axis=0)
    far = ~np.isfinite(nearest)
    if far.any():  # points far from every seed: search without a bound
        for ((dist, seed), _), (tree, _) in zip(found, trees):
            if tree is not None:
                dist[far], seed[far] = tree.query(pts[far])
        nearest = np.min([dist for (dist, _), _ in found], axis=0)
    for index, ((dist, seed), spacing) in enumerate(found):
        rows = np.flatnonzero(dist <= nearest + 2.0 * spacing)
        if rows.size:
            yield index, model.faces[index], rows, model.faces[index].seed_uv[seed[rows]]


def _query(tree, pts: np.ndarray, reach: float):
    """Nearest seed of each point within ``reach`` (inf and an out-of-range index beyond)."""
    if tree is None:
        return np.full(len(pts), np.inf), np.zeros(len(pts), dtype=int)
    dist, seed = tree.query(pts, distance_upper_bound=reach)
    return dist, np.minimum(seed, tree.n - 1)


def _trees(model: CadModel, coordinates) -> FaceTrees:
    """k-d trees of each face's seeds (in ``coordinates``), with the face's largest seed gap (mm).

    The callers keep them on the model (``seed_trees_xyz``, ``seed_trees_along``): built once each.
    """
    from scipy.spatial import cKDTree

    trees = []
    for face in model.faces:
        if face.seed_mm.shape[0] == 0:
            trees.append((None, 0.0))
            continue
        seeds = coordinates(face)
        tree = cKDTree(seeds)
        gap = tree.query(seeds, k=2)[0][:, 1].max() if seeds.shape[0] > 1 else model.seed_spacing_mm
        trees.append((tree, float(max(gap, model.seed_spacing_mm))))
    return trees


# ---------------------------------------------------------------------- small helpers


class _Best:
    """The best candidate so far for each of n queries (highest score)."""

    def __init__(self, n: int):
        self.xyz, self.dist = np.full((n, 3), np.nan), np.full(n, np.nan)
        self.face, self.uv, self.score = np.full(n, -1), np.full((n, 2), np.nan), np.full(n, -np.inf)

    def offer(self, rows, xyz, dist, index: int, uv, score) -> None:
        better = score > self.score[rows]
        rows = rows[better]
        self.xyz[rows], self.dist[rows], self.uv[rows] = xyz[better], dist[better], uv[better]
        self.face[rows], self.score[rows] = index, score[better]

    def hits(self, fallback: _Best | None = None) -> SurfaceHits:
        """The result; where nothing was found, ``fallback``'s candidate (still ``found`` False)."""
        found = np.isfinite(self.score)
        if fallback is not None:
            for name in ("xyz", "dist", "face", "uv"):
                getattr(self, name)[~found] = getattr(fallback, name)[~found]
        return SurfaceHits(self.xyz, self.dist, self.face, self.uv, found)


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("nd,nd->n", a, b)


def _solve2(a, b, c, d, rhs: np.ndarray) -> np.ndarray:
    """Solve the 2 x 2 systems [[a, b], [c, d]] x = rhs row by row (NaN where singular)."""
    det = a * d - b * c
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.column_stack([(d * rhs[:, 0] - b * rhs[:, 1]) / det, (a * rhs[:, 1] - c * rhs[:, 0]) / det])


def _normal_basis(d: np.ndarray) -> np.ndarray:
    """(2, 3) orthonormal rows normal to the unit vector ``d``."""
    helper = np.eye(3)[int(np.argmin(np.abs(d)))]
    e1 = np.cross(d, helper)
    e1 /= np.linalg.norm(e1)
    return np.array([e1, np.cross(d, e1)])


def _normal_basis_rows(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two (n, 3) unit vectors normal to each row of ``d`` (n, 3) and to each other."""
    helper = np.eye(3)[np.argmin(np.abs(d), axis=1)]
    e1 = np.cross(d, helper)
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    return e1, np.cross(d, e1)
