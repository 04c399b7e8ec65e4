"""Plane polygons: the convex outline of points, containment, offsets and distances.

The one place in mppf where point-in-polygon and outline geometry are written. Polygons
are ``(k, 2)`` arrays of corners in order, not repeated at the end; lengths in mm.
"""

from __future__ import annotations

import numpy as np

from mppf.core.errors import GeometryError, InputError

MITER_LIMIT = 4.0
"""A grown corner moves at most this many margins from the original corner (sharp corners are bevelled)."""


def as_polygon(corners, name: str = "polygon") -> np.ndarray:
    """``corners`` as a finite ``(k, 2)`` float array with at least 3 corners.

    Raises
    ------
    InputError
        Wrong shape, fewer than 3 corners, or non-finite coordinates.
    """
    pts = np.asarray(corners, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] < 3 or not np.all(np.isfinite(pts)):
        raise InputError(f"{name} must be at least 3 finite (x, y) corners, got shape {pts.shape}")
    return pts


HULL_TOLERANCE = 1e-12
"""Points within this fraction of the cloud's size of an outline edge's line are on the edge, not corners."""


def convex_outline_index(points_xy, what: str = "the points") -> np.ndarray:
    """Indices of the points on their convex outline, counter-clockwise from the lowest of the leftmost.

    Quickhull, vectorised over the points: the outline from the leftmost to the rightmost
    point and back, each edge split at the point farthest outside it until none is. Points
    on an edge (within :data:`HULL_TOLERANCE` of the cloud's size) and repeated points are
    not corners. The same corners as scipy's ``ConvexHull(points).vertices`` without
    importing scipy (0.2 - 0.4 s of a small ``mppf register``).

    Parameters
    ----------
    points_xy : (n, 2) float, mm
    what : str
        What the points are, for the error message.

    Returns
    -------
    (k,) int

    Raises
    ------
    GeometryError
        Fewer than 3 points, or all of them on one line (no area).
    """
    pts = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    if pts.shape[0] < 3:
        raise GeometryError(f"{what} have no outline: {pts.shape[0]} point(s), at least 3 are needed")
    corners = _quickhull(pts)
    if corners.size < 3:
        raise GeometryError(f"{what} have no area in the plane (all {pts.shape[0]} on one line)",
                            hint="check the file: a plate needs points spread over its area")
    return corners


def _quickhull(pts: np.ndarray) -> np.ndarray:
    """Corner indices (k,) of the convex outline of ``pts`` (n, 2), counter-clockwise; fewer than 3 when flat.

    Every edge of the outline found so far is split at once at its farthest outside point,
    round by round (about log2 of the corner count rounds), so the work is vectorised over
    all the points still outside, whatever the number of corners.
    """
    x, y = pts[:, 0], pts[:, 1]
    x_min, x_max = x.min(), x.max()
    left, right = np.flatnonzero(x == x_min), np.flatnonzero(x == x_max)
    first, last = int(left[np.argmin(y[left])]), int(right[np.argmax(y[right])])  # lowest leftmost, highest rightmost
    if first == last:  # every point the same
        return np.array([first], dtype=np.intp)
    tolerance = HULL_TOLERANCE * float(max(x_max - x_min, y.max() - y.min()))
    chain = np.array([first, last], dtype=np.intp)  # the corners so far, counter-clockwise; edge i: chain[i] -> [i + 1]
    candidates = np.arange(pts.shape[0])
    depth = _beyond(pts[first], pts[last], pts)  # right of first -> last: below, outside edge 0; above: edge 1
    edge = (depth < 0).astype(np.intp)
    depth = np.abs(depth)
    keep = depth > tolerance * float(np.hypot(*(pts[last] - pts[first])))
    candidates, edge, depth = candidates[keep], edge[keep], depth[keep]
    while candidates.size:
        # the farthest candidate of each edge that has any becomes a corner between its ends
        deepest = np.full(chain.size, -np.inf)
        np.maximum.at(deepest, edge, depth)
        heads = depth == deepest[edge]  # of equally far ones any: the last pass drops those inside a side
        far = np.full(chain.size, -1, dtype=np.intp)
        far[edge[heads]] = candidates[heads]
        split = far >= 0
        place = np.cumsum(1 + split) - (1 + split)  # where each old corner goes in the new chain
        grown = np.empty(chain.size + int(split.sum()), dtype=np.intp)
        grown[place], grown[place[split] + 1] = chain, far[split]
        # each candidate is now outside (a -> far), outside (far -> b), or inside the outline
        a, f, b = pts[chain[edge]], pts[far[edge]], pts[chain[(edge + 1) % chain.size]]
        to_a, to_b = _beyond(a, f, pts[candidates]), _beyond(f, b, pts[candidates])
        on_a = to_a > tolerance * np.hypot(*(f - a).T)
        on_b = to_b > tolerance * np.hypot(*(b - f).T)
        keep = on_a | on_b
        candidates, depth = candidates[keep], np.where(on_a, to_a, to_b)[keep]
        edge, chain = np.where(on_a, place[edge], place[edge] + 1)[keep], grown
    # a corner taken among points on one side (equally far from the edge split) is on that side: drop it
    while chain.size > 2:
        prev, nxt = pts[np.roll(chain, 1)], pts[np.roll(chain, -1)]
        flat = _beyond(prev, nxt, pts[chain]) <= tolerance * np.hypot(*(nxt - prev).T)
        if not flat.any():
            break
        chain = chain[~flat]
    return chain


def _beyond(a: np.ndarray, b: np.ndarray, p: np.ndarray) -> np.ndarray:
    """How far each point ``p`` (m, 2) lies right of the line a -> b (outside a counter-clockwise edge), times |ab|.
    ``a`` and ``b`` (2,) or one per point (m, 2)."""
    ab, rel = np.asarray(b - a).reshape(-1, 2), np.asarray(p - a).reshape(-1, 2)
    return ab[:, 1] * rel[:, 0] - ab[:, 0] * rel[:, 1]


def convex_outline(points_xy, what: str = "the points") -> np.ndarray:
    """The convex outline of points: ``(k, 2)`` corners, counter-clockwise, mm.

    Raises
    ------
    GeometryError
        Fewer than 3 points, or all of them on one line (see :func:`convex_outline_index`).
    """
    pts = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    return pts[convex_outline_index(pts, what)]


def area(polygon) -> float:
    """Signed area (mm^2): positive for a counter-clockwise polygon (shoelace formula)."""
    p = np.asarray(polygon, dtype=float)
    return 0.5 * float(np.sum(p[:, 0] * np.roll(p[:, 1], -1) - np.roll(p[:, 0], -1) * p[:, 1]))


def perimeter(polygon) -> float:
    """Length of the closed outline (mm)."""
    p = np.asarray(polygon, dtype=float)
    return float(np.linalg.norm(np.roll(p, -1, axis=0) - p, axis=1).sum())


def contains(polygon, points_xy, tolerance_mm: float = 0.0) -> np.ndarray:
    """Which points lie inside a polygon (even-odd rule; any simple polygon, either direction).

    Parameters
    ----------
    polygon : (k, 2) float, mm
    points_xy : (n, 2) float, mm
    tolerance_mm : float
        Points within this distance of the outline count as inside (>= 0).

    Returns
    -------
    (n,) bool
    """
    poly = np.asarray(polygon, dtype=float)
    pts = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    a = poly
    b = np.roll(poly, -1, axis=0)
    # the points sorted by y once: an edge can only be crossed by the ray of a point with y in [lo, hi) of
    # the edge, a slice of that order (k edges cost about n times the edges a horizontal line meets, not k n)
    order = np.argsort(pts[:, 1], kind="stable")
    x, y = pts[order, 0], pts[order, 1]
    low = np.searchsorted(y, np.minimum(a[:, 1], b[:, 1]), side="left")
    high = np.searchsorted(y, np.maximum(a[:, 1], b[:, 1]), side="left")
    flips = np.zeros(pts.shape[0], dtype=bool)
    for (ax, ay), (bx, by), i, j in zip(a, b, low, high):
        if i < j:  # the points of the band: (ay > y) != (by > y) there
            x_at = ax + (y[i:j] - ay) * (bx - ax) / (by - ay)
            flips[i:j] ^= x[i:j] < x_at
    inside = np.zeros(pts.shape[0], dtype=bool)
    inside[order] = flips
    if tolerance_mm > 0:
        inside |= distance_to_outline(poly, pts) <= tolerance_mm
    return inside


def closest_on_outline(polygon, points_xy, *, closed: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Closest point of a polygon's outline (or of a set of segments) to each point.

    Parameters
    ----------
    polygon : (k, 2) float, mm
        Corners; with ``closed`` the last corner joins the first.
    points_xy : (n, 2) float, mm
    closed : bool
        False: the segments ``polygon[i] -> polygon[i + 1]`` only (an open chain).

    Returns
    -------
    closest : (n, 2) float, mm
    edge : (n,) int
        Index of the segment (starting at corner ``edge``) the closest point lies on.
    """
    a = np.asarray(polygon, dtype=float)
    b = np.roll(a, -1, axis=0)
    if not closed:
        a, b = a[:-1], b[:-1]
    return closest_on_segments(points_xy, a, b)


def closest_on_segments(points_xy, seg_a, seg_b) -> tuple[np.ndarray, np.ndarray]:
    """Closest point on any of the segments ``seg_a[j] -> seg_b[j]`` to each point.

    Parameters
    ----------
    points_xy : (n, 2) float
    seg_a, seg_b : (k, 2) float
        Segment ends.

    Returns
    -------
    closest : (n, 2) float
    segment : (n,) int
    """
    pts = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    a = np.asarray(seg_a, dtype=float)
    ab = np.asarray(seg_b, dtype=float) - a
    # (n, k) per coordinate, in place: a tenth of the time of (n, k, 2) einsums on the outline fit's sizes
    dx = pts[:, 0, None] - a[None, :, 0]
    dy = pts[:, 1, None] - a[None, :, 1]
    t = (dx * ab[:, 0] + dy * ab[:, 1]) / np.maximum(np.einsum("kd,kd->k", ab, ab), 1e-12)
    np.clip(t, 0.0, 1.0, out=t)
    dx -= t * ab[:, 0]
    dy -= t * ab[:, 1]
    dx *= dx
    dy *= dy
    best = np.argmin(dx + dy, axis=1)
    return a[best] + t[np.arange(pts.shape[0]), best][:, None] * ab[best], best


def distance_to_outline(polygon, points_xy) -> np.ndarray:
    """Distance (mm, >= 0) of each point to the polygon's outline, inside or outside."""
    pts = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    closest, _ = closest_on_outline(polygon, pts)
    return np.linalg.norm(pts - closest, axis=1)


def distance_outside(polygon, points_xy) -> np.ndarray:
    """Distance (mm) of each point outside the polygon; 0 for the points inside."""
    pts = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    return np.where(contains(polygon, pts), 0.0, distance_to_outline(polygon, pts))


def inward_normals(seg_a, seg_b, counter_clockwise: bool = True) -> np.ndarray:
    """Unit normals of the segments pointing into the polygon they bound.

    Parameters
    ----------
    seg_a, seg_b : (k, 2) float
        Segment ends of a polygon's edges.
    counter_clockwise : bool
        The polygon's direction (the inside is on the left of a counter-clockwise edge).
    """
    edge = np.asarray(seg_b, dtype=float) - np.asarray(seg_a, dtype=float)
    left = np.column_stack([-edge[:, 1], edge[:, 0]]) / np.maximum(np.linalg.norm(edge, axis=1), 1e-12)[:, None]
    return left if counter_clockwise else -left


def offset_convex(corners, margin_mm: float) -> np.ndarray:
    """A convex polygon grown outward by a margin, with mitred corners.

    Each edge is moved outward by ``margin_mm`` along its unit outward normal; the new
    corners are where adjacent moved edges meet. At a corner with the outward normals
    ``n1``, ``n2`` of its two edges that point is ``c + margin (n1 + n2) / (1 + n1 . n2)``,
    which stays well defined for nearly parallel edges (it tends to the simple vertex
    offset ``c + margin n``). At a sharp corner (the miter longer than ``MITER_LIMIT``
    margins) the corner is moved ``MITER_LIMIT`` margins along its bisector instead.
    Repeated corners (edges shorter than 1e-9 mm) are dropped first.

    Parameters
    ----------
    corners : (k, 2) float, mm
        Corners of a convex polygon in order (either direction), not repeated at the end.
    margin_mm : float
        Width of the band (>= 0).

    Returns
    -------
    (k', 2) float, mm
        The grown polygon's corners, in the same order (k' = k unless corners repeat).

    Raises
    ------
    InputError
        Fewer than 3 distinct corners, or a negative or non-finite margin.
    """
    pts = np.asarray(corners, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2 or not np.all(np.isfinite(pts)):
        raise InputError(f"polygon corners must be finite (k, 2) coordinates, got shape {pts.shape}")
    if not (np.isfinite(margin_mm) and margin_mm >= 0):
        raise InputError(f"polygon offset must be a finite length >= 0, got {margin_mm} mm")
    keep = np.linalg.norm(pts - np.roll(pts, -1, axis=0), axis=1) > 1e-9
    pts = pts[keep]
    if pts.shape[0] < 3:
        raise InputError(f"a polygon needs at least 3 distinct corners, got {pts.shape[0]}")
    if margin_mm == 0:
        return pts.copy()
    edge = np.roll(pts, -1, axis=0) - pts                   # edge i: corner i -> corner i + 1
    turn = 1.0 if area(pts) >= 0 else -1.0                  # +1: counter-clockwise
    normal = turn * np.column_stack([edge[:, 1], -edge[:, 0]]) / np.linalg.norm(edge, axis=1)[:, None]
    n_in, n_out = np.roll(normal, 1, axis=0), normal        # the edges ending / starting at each corner
    miter = (n_in + n_out) / np.maximum(1.0 + np.einsum("kd,kd->k", n_in, n_out), 1e-12)[:, None]
    length = np.linalg.norm(miter, axis=1)
    sharp = length > MITER_LIMIT
    if sharp.any():
        bisector = n_in[sharp] + n_out[sharp]
        size = np.linalg.norm(bisector, axis=1)[:, None]
        # opposite normals (a hairpin): the bisector is undefined, move along the edge direction
        fallback = edge[sharp] / np.linalg.norm(edge[sharp], axis=1)[:, None]
        direction = np.where(size > 1e-9, bisector / np.maximum(size, 1e-12), -fallback)
        miter[sharp] = MITER_LIMIT * direction
    return pts + margin_mm * miter


def moments(polygon) -> tuple[float, np.ndarray, np.ndarray]:
    """Area, area centroid and central second moments of a polygon.

    Computed about the corners' mean, so hull-scale coordinates (1e5 mm) lose no accuracy.

    Parameters
    ----------
    polygon : (k, 2) float, mm
        Corners in order (either direction).

    Returns
    -------
    area_mm2 : float
        Absolute area.
    centroid : (2,) float, mm
    second : (2, 2) float, mm^2
        Central second moments of the area divided by the area (the area's covariance).

    Raises
    ------
    GeometryError
        The polygon has no area.
    """
    poly = np.asarray(polygon, dtype=float)
    ref = poly.mean(axis=0)
    x0, y0 = (poly - ref).T
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    cross = x0 * y1 - x1 * y0
    signed = cross.sum() / 2.0
    if abs(signed) < 1e-12:
        raise GeometryError("the outline of the plate has no area")
    cx = ((x0 + x1) * cross).sum() / (6.0 * signed)
    cy = ((y0 + y1) * cross).sum() / (6.0 * signed)
    ixx = ((x0 * x0 + x0 * x1 + x1 * x1) * cross).sum() / 12.0
    iyy = ((y0 * y0 + y0 * y1 + y1 * y1) * cross).sum() / 12.0
    ixy = ((x0 * y1 + 2 * x0 * y0 + 2 * x1 * y1 + x1 * y0) * cross).sum() / 24.0
    second = np.array([[ixx - signed * cx * cx, ixy - signed * cx * cy],
                       [ixy - signed * cx * cy, iyy - signed * cy * cy]]) / signed
    return float(abs(signed)), ref + np.array([cx, cy]), second


def convex_inset(polygon, points_xy) -> np.ndarray:
    """Signed distance of each point inside a convex polygon: > 0 inside, < 0 outside.

    The smallest distance to the polygon's edge lines (for points inside, the distance to
    the outline; outside, to the nearest edge's line). Cheap for many points: (n, k) work.

    Parameters
    ----------
    polygon : (k, 2) float, mm
        A convex polygon's corners in order (either direction).
    points_xy : (n, 2) float, mm

    Returns
    -------
    (n,) float, mm
    """
    poly = np.asarray(polygon, dtype=float)
    pts = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    normals = inward_normals(poly, np.roll(poly, -1, axis=0), counter_clockwise=area(poly) >= 0)
    offsets = np.einsum("kd,kd->k", normals, poly)
    return (pts @ normals.T - offsets).min(axis=1)
