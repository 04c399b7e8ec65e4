"""Nearest neighbours of point clouds: the k-d tree of the registration path (pykdtree).

:class:`KDTree` wraps pykdtree's tree with the answers of ``scipy.spatial.cKDTree.query``:
``(distances, indices)``, 1-D for ``k = 1`` and ``(m, k)`` otherwise, indices as ``intp``
(pykdtree gives ``uint32``), and a missing neighbour (fewer than ``k`` points in the tree, or
none closer than ``distance_upper_bound``, a strict bound as scipy's) at distance ``inf``
with index ``n``. Points are kept as float64 (pykdtree refuses queries of another dtype
than its tree's, so queries are converted too); distances are Euclidean, computed from the
same squared sums as ``sqrt(((q - p) ** 2).sum(axis=1))`` (bit for bit, which
:class:`mppf.registration.icp.Nearest` relies on).

Why not scipy's tree here: pykdtree builds about 3 times and queries about 1.6 times
faster on one thread, and imports in a few milliseconds where ``scipy.spatial`` takes
0.2 - 0.4 s of a 10,000-point ``mppf register`` (docs/math-registration.md section 9).
Ball and pair queries (``query_ball_point``, ``query_pairs``) are not here: mppf.measure
keeps scipy's ``cKDTree`` for them.

Threads: pykdtree runs its queries on OpenMP threads, one per core by default. Their
start-up and spin-waiting cost more CPU time than they save on small batches (a
1,000-point query took 8 ms of CPU with two threads on the 2 shared cores, 0.6 ms on
one), so a query of fewer than :data:`PARALLEL_QUERY` points runs on one thread:
threadpoolctl's OpenMP limit around the call, which sets the calling thread's own OpenMP
thread count (so Python threads querying at once each limit their own) and restores it
after. Larger queries use OpenMP's default, as scipy's ``workers=-1`` did before.

Query order: :func:`spatial_order` orders points so that neighbours follow each other; a
query in that order walks the tree's branches in turn, with the same answers per point
(the ICP's queries, :class:`mppf.registration.icp.Nearest`, and the local fits' neighbours,
:func:`mppf.measure.localfit.spatial_query`).
"""

from __future__ import annotations

import numpy as np

LEAF_SIZE = 16
"""Points per leaf of the tree (pykdtree's and scipy's default)."""

PARALLEL_QUERY = 20000
"""Queries of at least this many points run on OpenMP's default thread count; smaller ones on one thread."""

_OPENMP: list = []  # the threadpoolctl controller of the OpenMP libraries loaded with pykdtree, made on first use


def _one_thread():
    """A context in which this thread's OpenMP parallel regions (pykdtree's queries) run on one thread."""
    if not _OPENMP:
        from threadpoolctl import ThreadpoolController

        _OPENMP.append(ThreadpoolController().select(user_api="openmp"))
    return _OPENMP[0].limit(limits=1)


class KDTree:
    """A k-d tree of ``n`` points in ``d`` dimensions for k-nearest-neighbour queries.

    Parameters
    ----------
    points : (n, d) float
        The points (any unit; distances come back in the same unit), n >= 1. Kept as a
        float64 array: do not change it while the tree is in use.
    leafsize : int
        Points per leaf.

    Attributes
    ----------
    data : (n, d) float64
        The points of the tree.
    n : int
        Number of points.

    Raises
    ------
    ValueError
        ``points`` is not a non-empty (n, d) array.
    """

    def __init__(self, points, leafsize: int = LEAF_SIZE):
        from pykdtree.kdtree import KDTree as _PyKDTree

        data = np.ascontiguousarray(points, dtype=np.float64)
        if data.ndim != 2 or data.shape[0] == 0 or data.shape[1] == 0:
            raise ValueError(f"a k-d tree needs a non-empty (n, d) array of points, got shape {data.shape}")
        self.data = data
        self.n = int(data.shape[0])
        self._tree = _PyKDTree(data, leafsize=leafsize)

    def query(self, points, k: int = 1, distance_upper_bound: float = np.inf) -> tuple[np.ndarray, np.ndarray]:
        """The ``k`` nearest tree points of each query point, nearest first.

        Parameters
        ----------
        points : (m, d) float
            Query points, in the tree's unit.
        k : int
            Neighbours per point, >= 1.
        distance_upper_bound : float
            Only neighbours closer than this (strictly) are returned; the others are missing.

        Returns
        -------
        distances : (m,) float64 for k = 1, else (m, k)
            Euclidean distances; ``inf`` for a missing neighbour.
        indices : (m,) intp for k = 1, else (m, k)
            Rows of :attr:`data`; ``n`` for a missing neighbour.
        """
        if k < 1:
            raise ValueError(f"k must be at least 1, got {k}")
        pts = np.ascontiguousarray(points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != self.data.shape[1]:
            raise ValueError(f"query points must be (m, {self.data.shape[1]}), got shape {pts.shape}")
        m, found = pts.shape[0], min(k, self.n)
        if m == 0:
            dist, idx = np.empty((0, found)), np.empty((0, found), dtype=np.intp)
        else:
            bound = None if not np.isfinite(distance_upper_bound) else float(distance_upper_bound)
            if m >= PARALLEL_QUERY:
                dist, idx = self._tree.query(pts, k=found, distance_upper_bound=bound)
            else:
                with _one_thread():
                    dist, idx = self._tree.query(pts, k=found, distance_upper_bound=bound)
            dist, idx = dist.reshape(m, found), idx.reshape(m, found).astype(np.intp)
        if found < k:  # pykdtree leaves the slots past n undefined: scipy's inf and n
            dist = np.hstack([dist, np.full((m, k - found), np.inf)])
            idx = np.hstack([idx, np.full((m, k - found), self.n, dtype=np.intp)])
        if k == 1:
            return dist[:, 0], idx[:, 0]
        return dist, idx


def spatial_order(points: np.ndarray, strips: int = 64) -> np.ndarray:
    """(n,) int: an order of ``points`` (n, d) in which neighbours follow each other.

    Strips across the points' largest coordinate extent, each walked along the second largest:
    queries of a k-d tree in this order walk its branches in turn (fewer cache misses).
    """
    if points.shape[0] < 2 or points.shape[1] < 2:
        return np.argsort(points[:, 0], kind="stable")
    extent = np.ptp(points, axis=0)
    first, second = np.argsort(extent)[::-1][:2]
    width = max(float(extent[first]) / strips, 1e-9)
    return np.lexsort((points[:, second], np.floor(points[:, first] / width)))
