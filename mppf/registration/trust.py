"""Whether a registration can be believed: the noise floor, the residual against it, ties of starts.

A registration that stopped iterating is not yet a registration that found the pose: from a
wrong start ICP settles in a pose turned by half a turn as readily as in the right one. So
every result is judged (``docs/math-registration.md``, section 10):

- :func:`noise_floor_mm`: the residual the right pose would leave, from the clouds themselves:
  the source's scatter about local quadrics through its neighbours, and the target's
  scatter and sampling (each target point against the tangent plane of its nearest other
  point), added in quadrature;
- :func:`plane_residuals`: the normal distances of (a sample of) the moved source to the
  target's local planes at their closest points; the robust scale of those is the residual
  compared with the floor (:data:`FAR_FACTOR`);
- :func:`tie`: two poses fit equally when the runner-up's residuals exceed the best's by less
  than the noise (in quadrature), or by nothing that the sample shows beyond chance.

Lengths in mm.
"""

from __future__ import annotations

import numpy as np

from mppf.core.defaults import MAD_SCALE
from mppf.core.kdtree import KDTree
from mppf.core.transform import apply_tf
from mppf.registration.target import Cloud, RegistrationTarget, local_axes

NOISE_NEIGHBOURS = 16
"""Neighbours of the local quadric that gives a point's scatter (the point included)."""

NOISE_POINTS = 1500
"""Points (a seeded sample) on which a cloud's noise and a pose's residuals are evaluated."""

NOISE_TREE_POINTS = 30000
"""A source's scatter is judged among at most this many of its points (their neighbours)."""

FAR_FACTOR = 3.0
"""A residual above this many noise floors is "far above the noise": not the right pose of the same shape."""

TIE_NOISE_FRACTION = 0.5
"""Two poses tie when the runner-up's extra residual (in quadrature) is below this fraction of the floor ..."""

TIE_SIGMAS = 3.0
"""... or when the sample shows the difference by fewer than this many standard errors."""

CLIP_FLOORS = 4.0
"""Squared residuals are clipped at this many noise floors in the tie test (outliers, partial overlap)."""


def sample_index(n: int, count: int = NOISE_POINTS, seed: int = 0) -> np.ndarray:
    """A seeded, sorted sample of ``min(n, count)`` indices of ``n`` points."""
    if n <= count:
        return np.arange(n)
    return np.sort(np.random.default_rng(seed).choice(n, size=count, replace=False))


def quadric_scatter_mm(points: np.ndarray, tree, sample: np.ndarray) -> float:
    """Robust scatter (mm) of the ``sample`` points about local quadrics through their neighbours.

    Each sample point's :data:`NOISE_NEIGHBOURS` nearest points are put in their PCA frame
    and a quadric ``z = a + b x + c y + d x^2 + e x y + f y^2`` is fitted by least squares;
    the point's own residual, divided by ``sqrt(1 - h)`` (``h`` its leverage), has the
    point noise as its scale: 1.4826 times the median of their absolute values.
    """
    k = min(NOISE_NEIGHBOURS, points.shape[0])
    if k < 8:
        return 0.0
    _, nb = tree.query(points[sample], k=k)
    hood = points[nb] - points[sample][:, None, :]                       # (m, k, 3), the point first
    vec = local_axes(hood)
    local = np.matmul(hood, vec)                                          # column 0 along the normal
    radius = np.maximum(np.abs(local[..., 1:]).max(axis=(1, 2)), 1e-9)[:, None]
    x, y, z = local[..., 2] / radius, local[..., 1] / radius, local[..., 0]
    design = np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=-1)
    normal = np.matmul(design.transpose(0, 2, 1), design) + 1e-12 * np.eye(6)
    inverse = np.linalg.inv(normal)
    coef = np.matmul(inverse, np.matmul(design.transpose(0, 2, 1), z[..., None]))[..., 0]
    row = design[:, 0, :]
    residual = z[:, 0] - np.einsum("mi,mi->m", row, coef)
    leverage = np.clip(np.einsum("mi,mij,mj->m", row, inverse, row), 0.0, 0.95)
    return float(MAD_SCALE * np.median(np.abs(residual) / np.sqrt(1.0 - leverage)))


def sampling_scatter_mm(target: RegistrationTarget, sample: np.ndarray) -> float:
    """Robust scale (mm) of the target's sample points off the tangent plane of their nearest other point.

    It holds the target's own noise (twice) and the error of a tangent plane one point
    spacing away on a curved surface: what a closest-point plane metric cannot get below.
    """
    if target.n_points < 3:
        return 0.0
    _, nb = target.tree.query(target.points[sample], k=2)
    other = nb[:, 1]
    offset = target.points[sample] - target.points[other]
    residual = np.einsum("ij,ij->i", offset, target.normals(other))
    return float(MAD_SCALE * np.median(np.abs(residual)))


def noise_floor_mm(source: Cloud, target: RegistrationTarget) -> float:
    """The residual the right pose would leave (mm): source scatter and target sampling in quadrature.

    The source's scatter is taken among at most :data:`NOISE_TREE_POINTS` of its points (a
    seeded sample); the target's is computed once per target.
    """
    points = source.points[sample_index(source.n_points, NOISE_TREE_POINTS)]
    s_source = quadric_scatter_mm(points, KDTree(points), sample_index(points.shape[0]))
    if target.sampling_mm is None:
        target.sampling_mm = sampling_scatter_mm(target, sample_index(target.n_points))
    return float(np.hypot(s_source, target.sampling_mm))


def plane_residuals(target: RegistrationTarget, points: np.ndarray, tf: np.ndarray) -> np.ndarray:
    """Normal distances (k,) of ``points`` moved by ``tf`` to the target's local plane at their closest point."""
    return point_residuals(target, points, tf)[0]


def point_residuals(target: RegistrationTarget, points: np.ndarray, tf: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(normal distances, closest-point distances), each (k,), of ``points`` moved by ``tf``."""
    moved = apply_tf(tf, points)
    distance, idx = target.tree.query(moved)
    return np.einsum("ij,ij->i", moved - target.points[idx], target.normals(idx)), distance


def robust_scale_mm(residual: np.ndarray) -> float:
    """1.4826 x the median absolute residual: the residual's scale, indifferent to a minority of outliers."""
    return float(MAD_SCALE * np.median(np.abs(residual)))


def tie(best: np.ndarray, other: np.ndarray, floor_mm: float, level_mm: float | None = None) -> bool:
    """Whether two poses fit equally well: their residuals (k,) on the same points, and the noise floor.

    The squared residuals are clipped at :data:`CLIP_FLOORS` times ``level_mm`` (default:
    the floor, or the best's robust scale when larger): outliers and parts outside the
    overlap count alike in both. A tie: the runner-up's mean exceeds the best's by less
    than ``(TIE_NOISE_FRACTION floor)^2``, or by fewer than :data:`TIE_SIGMAS` standard
    errors of the paired differences.
    """
    level = max(floor_mm, robust_scale_mm(best)) if level_mm is None else level_mm
    clip = (CLIP_FLOORS * max(level, 1e-9)) ** 2
    diff = np.minimum(other**2, clip) - np.minimum(best**2, clip)
    extra = float(diff.mean())
    error = float(diff.std(ddof=1) / np.sqrt(diff.size)) if diff.size > 1 else np.inf
    return extra <= (TIE_NOISE_FRACTION * floor_mm) ** 2 or extra <= TIE_SIGMAS * error


def judge(stop_converged: bool, stop_reason: str, residual_mm: float, floor_mm: float, tried: int,
          compared: bool) -> str:
    """The judgement of a registration: "converged", or "failed: ..." with the figures.

    Parameters
    ----------
    stop_converged, stop_reason : bool, str
        The ICP stop test of the last stage.
    residual_mm, floor_mm : float
        Robust residual at the result and the noise floor.
    tried : int
        Starts whose converged residuals were compared (the result among them).
    compared : bool
        The residual is comparable with the noise (False between a flat and a curved plate:
        the residual is then their difference in shape).
    """
    if not stop_converged:
        return f"failed: {stop_reason} (residual {residual_mm:.3g} mm, noise floor {floor_mm:.3g} mm)"
    if compared and residual_mm > FAR_FACTOR * max(floor_mm, 1e-9):
        starts = f"the best of {tried} starts" if tried > 1 else "the only start tried"
        return (f"failed: residual {residual_mm:.3g} mm is {residual_mm / max(floor_mm, 1e-9):.1f} x the noise "
                f"floor {floor_mm:.3g} mm at {starts}: the clouds differ in shape, overlap little, or the pose is "
                "wrong")
    return "converged"
