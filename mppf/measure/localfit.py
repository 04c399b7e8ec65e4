"""Local polynomial fits of deviations over the design plane: the tool of the form deviation and the outlier test.

At a centre ``c`` a polynomial ``d(x) = p(x - c)`` (a plane or a quadric) is fitted by
weighted least squares to the deviations of the ``k`` nearest points, with tricube weights
``(1 - (r / h)^3)^3`` of their distance ``r`` (``h`` just beyond the k-th: a LOESS fit). The
fit's value at ``c`` is the smoothed deviation; its variance is ``sigma^2 v`` with ``v``
from the weights (:attr:`LocalFits.variance`). The fits are vectorised over all centres in
chunks (memory stays below a few hundred MB for 200,000 points) and solve their small
normal equations batched (LAPACK; a Cholesky factorisation where one is singular). Fits
over the same neighbours (a quadric and a plane) share them (:func:`fits`); neighbours are
queried in a spatial order (:func:`spatial_query`). Positions in the design plane, mm.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from mppf.core.kdtree import spatial_order
from mppf.core.threads import worker_threads

CHUNK = 5000
"""Centres fitted at once (by each worker)."""

RIDGE = 1e-9
"""Relative ridge on the normal equations (degenerate neighbourhoods: collinear points)."""

QUADRIC = ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2))
"""Exponents (of x, y) of the quadric's terms; the plane's are the first three."""


@dataclass(frozen=True, eq=False)
class LocalFits:
    """Fits at ``m`` centres.

    Attributes
    ----------
    coef : (m, p) float
        Coefficients of the terms of :data:`QUADRIC` (first ``p``), in units of the
        neighbourhood radius ``radius`` (x and y divided by it).
    variance : (m,) float
        Variance of the value at the centre per unit noise variance.
    leverage : (m,) float
        Weight of the nearest point (the centre itself when it is a data point) in the
        value at the centre: the fit's own share of that point.
    radius : (m,) float, mm
        The tricube radius ``h``.
    hat : (m, k) float or None
        The weight of each neighbour's value in the value at the centre (with ``hat=True``):
        ``value = hat @ values[neighbours]``, ``variance = (hat**2).sum(axis=1)``.
    """

    coef: np.ndarray
    variance: np.ndarray
    leverage: np.ndarray
    radius: np.ndarray
    hat: np.ndarray | None = None

    @property
    def value(self) -> np.ndarray:
        """(m,) the fitted value at each centre."""
        return self.coef[:, 0]

    def at(self, rows: np.ndarray, offset_mm: np.ndarray) -> np.ndarray:
        """Values of the fits ``rows`` (j,) at offsets (j, 2) mm from their centres."""
        x = offset_mm / self.radius[rows][:, None]
        terms = QUADRIC[: self.coef.shape[1]]
        return sum(self.coef[rows, i] * x[:, 0] ** a * x[:, 1] ** b for i, (a, b) in enumerate(terms))


PARALLEL_QUERIES = 20000
"""Queries of a k-d tree from this many on run on every core."""


def spatial_query(tree, centres: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """(distances (m, k), indices (m, k)) of the ``k`` nearest points of ``tree`` (a ``cKDTree``) to each centre.

    The centres are queried in a spatial order (strips across u, along v in each) and the
    answers put back in their order: neighbouring queries walk the same branches of the
    tree, about three times faster than a scan's shuffled order, with the same answers.
    """
    if not centres.shape[0]:
        return np.empty((0, k)), np.empty((0, k), dtype=int)
    order = spatial_order(centres)
    workers = worker_threads() if centres.shape[0] >= PARALLEL_QUERIES else 1
    dist, idx = tree.query(centres[order], k=k, workers=workers)
    back = np.empty_like(order)
    back[order] = np.arange(order.size)
    return dist[back].reshape(-1, k), idx[back].reshape(-1, k)


def tricube(ratio: np.ndarray) -> np.ndarray:
    """Tricube weights of distances over the radius (0 beyond 1)."""
    r = np.clip(ratio, 0.0, 1.0)
    c = 1.0 - r * r * r
    return c * c * c


def cholesky_solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve the batched symmetric positive definite systems ``a x = b``: (m, p, p), (m, p, q) -> (m, p, q)."""
    m, p, _ = a.shape
    low = np.zeros_like(a)
    for j in range(p):
        diag = a[:, j, j] - np.einsum("mk,mk->m", low[:, j, :j], low[:, j, :j])
        low[:, j, j] = np.sqrt(np.maximum(diag, 1e-300))
        for i in range(j + 1, p):
            low[:, i, j] = (a[:, i, j] - np.einsum("mk,mk->m", low[:, i, :j], low[:, j, :j])) / low[:, j, j]
    y = np.zeros_like(b)
    for i in range(p):
        y[:, i] = (b[:, i] - np.einsum("mk,mkq->mq", low[:, i, :i], y[:, :i])) / low[:, i, i, None]
    x = np.zeros_like(b)
    for i in reversed(range(p)):
        x[:, i] = (y[:, i] - np.einsum("mk,mkq->mq", low[:, i + 1:, i], x[:, i + 1:])) / low[:, i, i, None]
    return x


def solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve the batched systems ``a x = b`` (m, p, p), (m, p, q) by LAPACK; by :func:`cholesky_solve` when one
    of them is singular in floating point (a neighbourhood without weight)."""
    try:
        return np.linalg.solve(a, b)
    except np.linalg.LinAlgError:
        return cholesky_solve(a, b)


def fit(uv: np.ndarray, values: np.ndarray, centres: np.ndarray, near: tuple[np.ndarray, np.ndarray], k: int,
        terms: int = 6, weight: np.ndarray | None = None, hat: bool = False) -> LocalFits:
    """Tricube-weighted local fits at ``centres`` over their ``k`` nearest points.

    Parameters
    ----------
    uv : (n, 2) float, mm
        Positions of the points.
    values : (n,) float
        Their deviations.
    centres : (m, 2) float, mm
        Where the fits are centred.
    near : ((m, K) float, (m, K) int)
        The centres' nearest points, sorted by distance, K >= k: (distances mm, indices), as
        :func:`spatial_query` returns them.
    k : int
        Points in each fit.
    terms : int
        3: a plane, 6: a quadric.
    weight : (n,) float, optional
        Extra weight of each point (0 leaves it out).
    hat : bool
        Also return the neighbours' weights in the values (:attr:`LocalFits.hat`).
    """
    return fits(uv, values, centres, near, k, (terms,), weight, hat)[0]


def fits(uv: np.ndarray, values: np.ndarray, centres: np.ndarray, near: tuple[np.ndarray, np.ndarray], k: int,
         terms=(6,), weight: np.ndarray | None = None, hat: bool = False) -> list[LocalFits]:
    """:func:`fit` for several term counts over the same ``k`` neighbours (one :class:`LocalFits` per entry of
    ``terms``): the neighbourhood, its weights and its terms are computed once and shared.

    With ``w`` the tricube weights and ``D`` (k, p) the terms of a centre's neighbours, the
    normal equations are ``(D' W D) c = D' W d``; the hat weights are ``W D (D' W D)^-1 e0``,
    whose squares sum to the variance and whose first entry (the nearest point) is the
    leverage.
    """
    distances, neighbours = near
    m = centres.shape[0]
    widest = max(terms)
    out = [(np.empty((m, t)), np.empty(m), np.empty(m), np.empty((m, k)) if hat else None) for t in terms]
    radius = np.empty(m)

    def chunk(lo: int) -> None:  # the centres lo:lo + CHUNK, written into ``out`` and ``radius``
        hi = min(lo + CHUNK, m)
        idx, dist = neighbours[lo:hi, :k], distances[lo:hi, :k]
        h = dist[:, -1] * (1.0 + 1e-6) + 1e-9
        w = tricube(dist / h[:, None])
        if weight is not None:
            w = w * weight[idx]
        x = (uv[idx, 0] - centres[lo:hi, 0, None]) / h[:, None]
        y = (uv[idx, 1] - centres[lo:hi, 1, None]) / h[:, None]
        design = np.stack([x ** a * y ** b for a, b in QUADRIC[:widest]], axis=-1)  # (m, k, p)
        weighted = w[..., None] * design
        normal = np.matmul(weighted.transpose(0, 2, 1), design)  # D' W D, (m, p, p)
        rhs = np.matmul(weighted.transpose(0, 2, 1), values[idx][..., None])[..., 0]  # D' W d
        radius[lo:hi] = h
        for t, (coef, variance, leverage, hats) in zip(terms, out):
            a = normal[:, :t, :t].copy()
            a += RIDGE * np.trace(a, axis1=1, axis2=2)[:, None, None] * np.eye(t)
            e0 = np.zeros((hi - lo, t))
            e0[:, 0] = 1.0
            sol = solve(a, np.stack([rhs[:, :t], e0], axis=-1))
            coef[lo:hi] = sol[..., 0]
            share = np.matmul(weighted[..., :t], sol[..., 1:])[..., 0]  # W D a^-1 e0: the hat weights
            variance[lo:hi] = (share * share).sum(axis=1)
            leverage[lo:hi] = share[:, 0]  # the nearest point's share
            if hat:
                hats[lo:hi] = share

    # the chunks are independent: on every core (numpy lets go of the GIL), each written in place
    starts = range(0, m, CHUNK)
    threads = worker_threads()
    if len(starts) > 1 and threads > 1:
        with ThreadPoolExecutor(threads) as pool:
            list(pool.map(chunk, starts))
    else:
        for lo in starts:
            chunk(lo)
    return [LocalFits(coef, variance, leverage, radius, hats) for coef, variance, leverage, hats in out]
