"""Triangle meshes of plates: triangulation of a (u, v) projection, edges, boundary, areas.

Triangles are ``(m, 3)`` int arrays of point indices; a plate's triangles are wound
counter-clockwise seen from its frame's +n side.
"""

from __future__ import annotations

import numpy as np

from mppf.core.errors import GeometryError, InputError

SLIVER_QUALITY = 0.05
"""Boundary triangles of a Delaunay triangulation with quality 4*sqrt(3)*A/sum(l^2)
below this (1 = equilateral, 0 = degenerate) are slivers of the convex hull."""

SLIVER_EDGE_FACTOR = 2.5
"""Boundary triangles with an edge longer than this times the median edge are removed too."""


def check_faces(faces, n_points: int) -> np.ndarray:
    """Mesh triangles as an ``(m, 3)`` int64 array of valid point indices, degenerate ones dropped.

    Raises
    ------
    InputError
        Wrong shape or type, or an index that is not a point.
    """
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


def triangle_areas(pts: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Areas (m,) of 3-D triangles, mm^2."""
    a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)


def signed_areas_2d(xy: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Signed areas (m,) of plane triangles, mm^2: positive when counter-clockwise."""
    a, b, c = xy[tri[:, 0]], xy[tri[:, 1]], xy[tri[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))


def wind_ccw(uv: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """Reverse a consistently wound mesh when most triangles run clockwise in (u, v)."""
    if np.sum(signed_areas_2d(uv, tri)) < 0:
        return tri[:, ::-1].copy()
    return tri


def triangulate(uv: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Delaunay triangles of the (u, v) projection without the convex hull's slivers.

    Boundary triangles that are slivers (quality below :data:`SLIVER_QUALITY`) or have
    an edge longer than :data:`SLIVER_EDGE_FACTOR` times the median edge are peeled off
    repeatedly, as long as their points stay in other triangles.
    """
    from scipy.spatial import Delaunay

    tri = Delaunay(uv).simplices.astype(np.int64)
    area_uv = signed_areas_2d(uv, tri)
    tri[area_uv < 0] = tri[area_uv < 0][:, ::-1]  # every triangle counter-clockwise
    tri = tri[np.abs(area_uv) > 1e-12 * float(np.ptp(uv, axis=0).max()) ** 2]  # no flat ones
    # each triangle's quality and sides once; peeling only updates which triangles are left
    a, b, c = pts[tri[:, 0]], pts[tri[:, 1]], pts[tri[:, 2]]
    sq = np.column_stack([np.sum((b - a) ** 2, 1), np.sum((c - b) ** 2, 1), np.sum((a - c) ** 2, 1)])
    quality = 4.0 * np.sqrt(3.0) * triangle_areas(pts, tri) / np.maximum(sq.sum(axis=1), 1e-300)
    sides, longest = np.sqrt(sq), np.sqrt(sq.max(axis=1))
    edge_of = np.unique(_edge_keys(tri), return_inverse=True)[1].reshape(3, -1)  # (3, m) edge of each side
    shared = np.bincount(edge_of.ravel())  # triangles left on each edge
    uses = np.bincount(tri.ravel(), minlength=pts.shape[0])  # triangles left at each point
    left = np.ones(len(tri), dtype=bool)
    while True:
        bad = (quality < SLIVER_QUALITY) | (longest > SLIVER_EDGE_FACTOR * np.median(sides[left]))
        on_boundary = (shared[edge_of] == 1).any(axis=0)
        candidates = np.flatnonzero(bad & on_boundary & left)
        if candidates.size == 0:
            return tri[left]
        # peel only triangles whose corners all stay in some other triangle
        kept = uses - np.bincount(tri[candidates].ravel(), minlength=pts.shape[0])
        removable = candidates[np.all(kept[tri[candidates]] > 0, axis=1)]
        if removable.size == 0:
            return tri[left]
        left[removable] = False
        uses -= np.bincount(tri[removable].ravel(), minlength=pts.shape[0])
        shared -= np.bincount(edge_of[:, removable].ravel(), minlength=len(shared))


def _edge_keys(tri: np.ndarray) -> np.ndarray:
    """One integer key per triangle side (3m,): sides 01, 12, 20 of every triangle."""
    pairs = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
    pairs.sort(axis=1)
    return pairs[:, 0] * (int(tri.max()) + 1) + pairs[:, 1]


def unique_edges(tri: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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
    edges, boundary = unique_edges(np.asarray(faces, dtype=np.int64))
    return edges[boundary]


def check_all_used(tri: np.ndarray, n_points: int) -> None:
    """Raise GeometryError when a point belongs to no triangle."""
    unused = np.flatnonzero(np.bincount(tri.ravel(), minlength=n_points) == 0)
    if unused.size:
        raise GeometryError(
            f"{unused.size} point(s) belong to no triangle (first: point {int(unused[0])}); "
            "duplicate points or mesh vertices without faces cannot be unfolded",
            hint="remove duplicate or loose points from the design",
        )


def edge_lengths(pts: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Lengths (k,) of the edges ``pts[edges[:, 0]] -> pts[edges[:, 1]]`` (2-D or 3-D points), mm."""
    return np.linalg.norm(pts[edges[:, 0]] - pts[edges[:, 1]], axis=1)


def triangles_in_own_plane(pts: np.ndarray, tri: np.ndarray):
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
