"""The fixed side of a registration, built once and passed to every ICP call.

A :class:`RegistrationTarget` holds the target points (checked), their k-d tree, their
plate frame and flatness, and computes on demand (once each) the local PCA normals of its
points and the moments of its outline in its plate plane. ``register_icp`` builds one
from an array, or takes one built by the caller (``compare`` registers a scan onto the
same design skin about twenty times). The moving side may be prepared once too: a
:class:`Cloud` (checked points, frame, flatness; :func:`prepare`). Lengths in mm.

:func:`build_target` keeps the last :data:`KEPT_TARGETS` targets it built, by the content of
their points: the loop compares every cycle's scans, and every rescan, with the same design
skin, so its tree, frame and normals are made once per plate, not once per comparison (the
normals alone were a sixth of a comparison's time). A target is never changed once built
(its normals are filled in once each, the same whoever asks first), so sharing it changes no
result.
"""

from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

from mppf.core.errors import GeometryError, InputError
from mppf.core.kdtree import KDTree
from mppf.core.polygon import convex_outline, moments
from mppf.core.transform import as_points
from mppf.geometry.check import check_plate
from mppf.geometry.frame import LocalFrame, fit_frame

KEPT_TARGETS = 4
"""Targets :func:`build_target` keeps for the next call with the same points (the latest used)."""

_kept: OrderedDict = OrderedDict()  # (name, shape, digest of the points) -> RegistrationTarget
_kept_lock = threading.Lock()

NORMAL_NEIGHBOURS = 10
"""Target points used for each local PCA normal (and the fewest points a point-to-plane target has)."""

FLAT_RATIO = 3e-3
"""A cloud is flat when its spread along its normal is below this fraction of its in-plane spread."""


def local_axes(hood: np.ndarray) -> np.ndarray:
    """(m, 3, 3) principal axes of ``m`` neighbourhoods (m, k, 3): eigenvectors as columns, the least spread
    (the local normal) first. A batched matmul for the covariances: 5 x faster than an einsum."""
    centred = hood - hood.mean(axis=1, keepdims=True)
    return np.linalg.eigh(np.matmul(centred.transpose(0, 2, 1), centred))[1]


def check_cloud(points, name: str, min_points: int = 3) -> np.ndarray:
    """One point set of a registration as an ``(n, 3)`` array: finite, enough points, spread over an area.

    Raises
    ------
    InputError
        Bad shape, or a NaN / infinite coordinate (the first one is named).
    GeometryError
        Fewer than ``min_points`` points, or points that do not span a plane.
    """
    pts = as_points(points, name=name)
    bad = ~np.all(np.isfinite(pts), axis=1)
    if bad.any():
        first = int(np.argmax(bad))
        raise InputError(
            f"{name}: point {first} has a NaN or infinite coordinate {pts[first].tolist()}",
            hint="remove or repair invalid points before registering",
        )
    check_min_points(pts.shape[0], name, min_points)
    return check_plate(pts, min_points=min_points, source=name)


def check_min_points(n: int, name: str, min_points: int) -> None:
    """Raise GeometryError when a registration has fewer than ``min_points`` points on one side."""
    if n < min_points:
        raise GeometryError(
            f"{name}: {n} point(s), registration needs at least {min_points} non-collinear points",
            hint="give more points",
        )


def spreads(frame: LocalFrame, points: np.ndarray) -> tuple[float, float]:
    """(in-plane RMS radius, RMS along the normal) of points in their frame, mm."""
    local = frame.to_local(points)
    return float(np.sqrt((local[:, :2] ** 2).sum(axis=1).mean())), float(local[:, 2].std())


def is_flat(frame: LocalFrame, points: np.ndarray) -> bool:
    """True when the points spread along their normal less than ``FLAT_RATIO`` of their in-plane spread."""
    radius, thickness = spreads(frame, points)
    return thickness < FLAT_RATIO * radius


def polygon_moments(points_2d: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Area (mm^2), area centroid (2,) and central second moments (2, 2) of the convex outline.

    Raises
    ------
    GeometryError
        The points do not span an area in the plane.
    """
    return moments(convex_outline(points_2d, "the points of the plate"))


@dataclass(eq=False, kw_only=True)
class Cloud:
    """A point set checked once for registration: its points, plate frame and flatness.

    Build it with :func:`prepare`; a source registered several times (from several starts)
    is checked and framed once.

    Attributes
    ----------
    points : (n, 3) float, mm
    frame : LocalFrame
        The points' plate frame (plate plane u, v; normal n).
    flat : bool
        The cloud is flat (see :func:`is_flat`).
    name : str
        What the points are, for messages.
    """

    points: np.ndarray
    frame: LocalFrame
    flat: bool
    name: str = "points"

    @property
    def n_points(self) -> int:
        """Number of points."""
        return int(self.points.shape[0])


@dataclass(eq=False, kw_only=True)
class RegistrationTarget(Cloud):
    """The fixed cloud of a registration: a :class:`Cloud` with its k-d tree. Build it with :func:`build_target`.

    Attributes
    ----------
    tree : mppf.core.kdtree.KDTree of ``points``
    sampling_mm : float or None
        The target's sampling scatter, mm (:func:`mppf.registration.trust.sampling_scatter_mm` of its
        seeded sample), set once by the first :func:`mppf.registration.trust.noise_floor_mm` that needs
        it; None until then.
    """

    tree: object
    sampling_mm: float | None = field(default=None, repr=False)
    _normals: np.ndarray | None = field(default=None, repr=False)
    _outline: tuple | None = field(default=None, repr=False)

    def __post_init__(self):
        # NaN: not computed yet; filled in place, so that threads sharing the target share the work
        self._normals = np.full(self.points.shape, np.nan)

    def normals(self, idx: np.ndarray) -> np.ndarray:
        """Unit normals (k, 3) of target points ``idx`` by local PCA (computed once each)."""
        # every component: another thread may be writing a row (NaN -> its value) while this one looks
        missing = idx[np.isnan(self._normals[idx]).any(axis=1)]
        if missing.size:
            missing = np.unique(missing)
            k = min(NORMAL_NEIGHBOURS, self.n_points)
            _, nb = self.tree.query(self.points[missing], k=k)
            self._normals[missing] = local_axes(self.points[nb])[:, :, 0]
        return self._normals[idx]

    def outline(self) -> tuple[float, np.ndarray, np.ndarray]:
        """Area, centroid (2,) and central second moments (2, 2) of the outline in the target's plane."""
        if self._outline is None:
            self._outline = polygon_moments(self.frame.to_local(self.points)[:, :2])
        return self._outline


def prepare(points, name: str = "source") -> Cloud:
    """``points`` checked (:func:`check_cloud`) with their plate frame, as a :class:`Cloud`."""
    pts = check_cloud(points, name)
    frame = fit_frame(pts)
    return Cloud(points=pts, frame=frame, flat=is_flat(frame, pts), name=name)


def build_target(points, name: str = "target") -> RegistrationTarget:
    """The registration target of ``points``: checked, with its k-d tree and plate frame.

    Parameters
    ----------
    points : (m, 3) float, mm
        At least 3 points spread over an area.
    name : str
        What the points are, for messages.

    Raises
    ------
    InputError, GeometryError
        See :func:`check_cloud`.
    """
    try:
        data = np.ascontiguousarray(points, dtype=np.float64)
    except (TypeError, ValueError):  # not an array of numbers: not kept, and prepare says what is wrong
        data = None
    key = None if data is None else (name, data.shape, hashlib.blake2b(data.tobytes(), digest_size=16).digest())
    with _kept_lock:
        if key is not None and key in _kept:
            _kept.move_to_end(key)
            return _kept[key]
    cloud = prepare(points if data is None else data.copy(), name)  # a kept one: its own copy
    if key is not None:
        cloud.points.flags.writeable = False  # shared by every caller with the same points: nobody changes it
    target = RegistrationTarget(points=cloud.points, frame=cloud.frame, flat=cloud.flat, name=name,
                                tree=KDTree(cloud.points))
    if key is not None:
        with _kept_lock:
            _kept[key] = target
            while len(_kept) > KEPT_TARGETS:
                _kept.popitem(last=False)
    return target
