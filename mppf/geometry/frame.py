"""The plate's own local frame: the best-fit plane, so the plate becomes z = D(u, v).

Hull plates are given in hull coordinates, where they are not height fields. The
local frame (u, v, n) puts the plate's best-fit plane (principal component analysis)
on u, v and its normal on n; in that frame a plate is a height field w = D(u, v).

Sign convention (deterministic, see ``docs/math-surfaces.md``):

1. ``n`` is chosen so that the plate is concave seen from +n (it bulges toward -n,
   like a bowl lying on the press bed), judged by the mean second derivative of a
   quadratic fitted in the frame, when that bulge is at least ``BULGE_MIN_MM``;
   for flatter plates and balanced saddles ``n`` has a world z component >= 0 (ties:
   its largest component positive).
2. ``u`` (the direction of largest spread) has its largest world component positive.
3. ``v = n x u``, so (u, v, n) is right-handed.

The origin is the centroid of the points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.errors import GeometryError, InputError
from mppf.core.kdtree import KDTree
from mppf.core.transform import as_points

BULGE_MIN_MM = 0.5
"""Smallest mean bulge (mm over the plate) that decides the sign of n; below, world z decides."""

FOLD_SLOPE_MAX = 1.0
"""Steepest slope |dw / d(u, v)| (45 degrees) between near neighbours that still counts as one layer."""

FOLD_GAP_FRACTION = 0.01
"""Height gap between near neighbours, as a fraction of the plate's in-plane size, that is tolerated."""

FOLD_NEIGHBOURS = 8
"""Nearest (u, v) neighbours each point is compared with."""

FOLD_OUTLIER_VOTES = 5
"""A point off at least this many of its 8 neighbours, all on one side, is an isolated outlier."""

FOLD_MIN_POINTS = 3
FOLD_MIN_FRACTION = 0.001
"""A fold needs at least this many (and this share of all) points next to another layer."""


@dataclass(frozen=True, eq=False)
class LocalFrame:
    """A right-handed orthonormal frame.

    Attributes
    ----------
    origin : (3,) float
        Origin in world coordinates, mm.
    axes : (3, 3) float
        Rows are the unit u, v, n axes in world coordinates.
    """

    origin: np.ndarray
    axes: np.ndarray

    def __post_init__(self):
        origin = np.asarray(self.origin, dtype=float).reshape(-1)
        axes = np.asarray(self.axes, dtype=float)
        if origin.shape != (3,) or axes.shape != (3, 3):
            raise InputError(f"a frame needs origin (3,) and axes (3, 3), got {origin.shape}, {axes.shape}")
        if not np.allclose(axes @ axes.T, np.eye(3), atol=1e-9) or np.linalg.det(axes) < 0:
            raise InputError("frame axes must be orthonormal and right-handed",
                             hint="rows u, v, n with n = u x v")
        object.__setattr__(self, "origin", origin)
        object.__setattr__(self, "axes", axes)

    def to_local(self, points) -> np.ndarray:
        """World points (n, 3) mm -> local (u, v, w) coordinates (n, 3) mm."""
        return (as_points(points) - self.origin) @ self.axes.T

    def to_world(self, points) -> np.ndarray:
        """Local points (n, 3) mm -> world coordinates (n, 3) mm."""
        return as_points(points) @ self.axes + self.origin

    @property
    def tf_local_world(self) -> np.ndarray:
        """(4, 4) transform mapping world coordinates into the local frame."""
        tf = np.eye(4)
        tf[:3, :3] = self.axes
        tf[:3, 3] = -self.axes @ self.origin
        return tf

    @property
    def tf_world_local(self) -> np.ndarray:
        """(4, 4) transform mapping local coordinates into the world."""
        tf = np.eye(4)
        tf[:3, :3] = self.axes.T
        tf[:3, 3] = self.origin
        return tf

    def to_dict(self) -> dict:
        """Origin and axes as plain lists (for JSON)."""
        return {"origin": self.origin.tolist(), "axes": self.axes.tolist()}


def _largest_component_positive(vector: np.ndarray) -> np.ndarray:
    return vector if vector[np.argmax(np.abs(vector))] > 0 else -vector


def _mean_bulge_mm(local: np.ndarray) -> float:
    """Mean second-order bulge of a quadratic fitted to local points (sign along +n).

    Coordinates are scaled by the half extents, so the value is the mm of rise at
    the plate's edge of the mean quadratic term (u'^2 + v'^2 coefficients summed).
    """
    u, v, w = local.T
    su = max(float(np.abs(u).max()), 1e-12)
    sv = max(float(np.abs(v).max()), 1e-12)
    s, t = u / su, v / sv
    design = np.column_stack([np.ones_like(s), s, t, s * s, s * t, t * t])
    coef = np.linalg.lstsq(design, w, rcond=None)[0]
    return float(coef[3] + coef[5])


def fit_frame(points) -> LocalFrame:
    """Best-fit-plane frame of a plate by principal component analysis.

    Parameters
    ----------
    points : (n, 3) float, mm, n >= 3, not collinear

    Returns
    -------
    LocalFrame
        Origin at the centroid; u the direction of largest spread, n the normal of
        the best-fit plane, signs as in the module docstring.

    Raises
    ------
    GeometryError
        Fewer than 3 points, or the points do not span a plane.
    """
    pts = as_points(points)
    if pts.shape[0] < 3:
        raise GeometryError(f"a plane needs at least 3 points, got {pts.shape[0]}")
    origin = pts.mean(axis=0)
    centred = pts - origin
    # eigen-decomposition of the 3x3 scatter matrix (ascending eigenvalues)
    eigval, eigvec = np.linalg.eigh(centred.T @ centred)
    if eigval[1] <= 1e-12 * max(eigval[2], 1e-300):
        raise GeometryError("the points do not span a plane (collinear or coincident)",
                            hint="a plate needs points spread over an area")
    u_axis = _largest_component_positive(eigvec[:, 2])
    n_axis = eigvec[:, 0]
    axes = np.array([u_axis, np.cross(n_axis, u_axis), n_axis])
    bulge = _mean_bulge_mm(centred @ axes.T)
    if abs(bulge) >= BULGE_MIN_MM:
        flip = bulge < 0
    elif abs(n_axis[2]) > 1e-9:
        flip = n_axis[2] < 0
    else:
        flip = n_axis[np.argmax(np.abs(n_axis))] < 0
    if flip:
        n_axis = -n_axis
    axes = np.array([u_axis, np.cross(n_axis, u_axis), n_axis])
    return LocalFrame(origin=origin, axes=axes)


def check_height_field(frame: LocalFrame, points, faces=None, *, source: str | None = None) -> None:
    """Raise GeometryError when the plate folds over in ``frame`` (not z = D(u, v)).

    With ``faces`` (a mesh, consistently wound): any triangle whose projection on the
    (u, v) plane is flipped against the majority means a fold. Without faces (a point
    cloud or grid): two near neighbours in (u, v) (the 8 nearest) whose heights differ
    by more than ``FOLD_SLOPE_MAX`` times their (u, v) distance plus
    ``FOLD_GAP_FRACTION`` of the plate size lie on distinct layers (or on a wall
    steeper than 45 degrees). Isolated scanner outliers are set aside first: points
    off at least 5 of their 8 neighbours by half that allowance, all on one side (a
    point of a steep or folded surface has neighbours above and below). The plate
    folds when at least 3 (and 0.1 %) of the remaining points each conflict with two
    or more neighbours.

    Parameters
    ----------
    frame : LocalFrame
    points : (n, 3) float, mm, world coordinates
    faces : (m, 3) int, optional
    source : str, optional
        Name of the plate (a file name) that starts the message.

    Raises
    ------
    GeometryError
    """
    where = f"{source}: " if source else ""
    local = frame.to_local(points)
    uv, w = local[:, :2], local[:, 2]
    size_mm = float(np.ptp(uv, axis=0).max())
    if faces is not None:
        _check_mesh_unfolded(uv, np.asarray(faces, dtype=np.int64), size_mm, where)
        return
    tolerance_mm = FOLD_GAP_FRACTION * size_mm
    # isolated outliers: a point off most of its neighbours (by half the allowance), all
    # on one side of it; points of a steep or folded surface have neighbours above and below
    dist, idx = _neighbours(uv)
    rise = w[idx] - w[:, None]
    off = np.abs(rise) > 0.5 * (FOLD_SLOPE_MAX * dist + tolerance_mm)
    one_side = np.all((rise > 0) | ~off, axis=1) | np.all((rise < 0) | ~off, axis=1)
    keep = ~((off.sum(axis=1) >= FOLD_OUTLIER_VOTES) & one_side)
    conflict = np.abs(rise) > FOLD_SLOPE_MAX * dist + tolerance_mm
    layered = keep & ((conflict & keep[idx]).sum(axis=1) >= 2)
    if layered.sum() >= max(FOLD_MIN_POINTS, FOLD_MIN_FRACTION * len(w)):
        raise GeometryError(
            f"{where}the plate folds over (or stands steeper than {np.degrees(np.arctan(FOLD_SLOPE_MAX)):.0f} degrees) "
            f"in its frame: {int(layered.sum())} points have neighbours in the plate plane at a height "
            f"differing by more than {FOLD_SLOPE_MAX:g} x their distance + {tolerance_mm:.3g} mm "
            f"(e.g. point {int(np.argmax(layered))})",
            hint="it is not a height field z = D(u, v): split the plate into parts that are",
        )


def _check_mesh_unfolded(uv: np.ndarray, tri: np.ndarray, size_mm: float, where: str) -> None:
    """Raise GeometryError when triangles (m, 3) of points projected to (n, 2) mm are flipped against the majority."""
    a, b, c = uv[tri[:, 0]], uv[tri[:, 1]], uv[tri[:, 2]]
    area2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    tiny = 1e-12 * size_mm * size_mm
    positive = int(np.count_nonzero(area2 > tiny))
    negative = int(np.count_nonzero(area2 < -tiny))
    flipped = min(positive, negative)
    if flipped:
        raise GeometryError(
            f"{where}the plate folds over in its own frame: {flipped} of {len(tri)} triangles "
            "are flipped when projected on its best-fit plane",
            hint="it is not a height field z = D(u, v); split the plate into parts that are",
        )


def _neighbours(uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distances and indices (n, k) of each point's nearest (u, v) neighbours, itself excluded."""
    k = min(FOLD_NEIGHBOURS + 1, len(uv))
    dist, idx = KDTree(uv).query(uv, k=k)
    return dist.reshape(len(uv), k)[:, 1:], idx.reshape(len(uv), k)[:, 1:]
