"""Local polynomial fits of deviations over the design plane: the tool of the form deviation and the outlier test.

At a centre ``c`` a polynomial ``d(x) = p(x - c)`` (a plane or a quadric) is fitted by
weighted least squares to the deviations of the ``k`` nearest points, with tricube weights
``(1 - (r / h)^3)^3`` of their distance ``r`` (``h`` just beyond the k-th: a LOESS fit). The
fit's value at ``c`` is the smoothed deviation; its variance is ``sigma^2 v`` with ``v``
from the weights (:attr:`LocalFits.variance`). The fits are vectorised over all centres in
chunks (memory stays below a few hundred MB for 200,000 points) and solve their small
normal equations by a batched Cholesky factorisation. Positions in the design plane, mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

CHUNK = 20000
"""Centres fitted at once."""

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


def tricube(ratio: np.ndarray) -> np.ndarray:
    """Tricube weights of distances over the radius (0 beyond 1)."""
    return np.clip(1.0 - np.clip(ratio, 0.0, 1.0) ** 3, 0.0, None) ** 3


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


def fit(uv: np.ndarray, values: np.ndarray, centres: np.ndarray, neighbours: np.ndarray, distances: np.ndarray,
        k: int, terms: int = 6, weight: np.ndarray | None = None, hat: bool = False) -> LocalFits:
    """Tricube-weighted local fits at ``centres`` over their ``k`` nearest points.

    Parameters
    ----------
    uv : (n, 2) float, mm
        Positions of the points.
    values : (n,) float
        Their deviations.
    centres : (m, 2) float, mm
        Where the fits are centred.
    neighbours, distances : (m, K) int, float
        The centres' nearest points (sorted by distance), K >= k.
    k : int
        Points in each fit.
    terms : int
        3: a plane, 6: a quadric.
    weight : (n,) float, optional
        Extra weight of each point (0 leaves it out).
    hat : bool
        Also return the neighbours' weights in the values (:attr:`LocalFits.hat`).
    """
    m = centres.shape[0]
    coef, variance = np.empty((m, terms)), np.empty(m)
    leverage, radius = np.empty(m), np.empty(m)
    hats = np.empty((m, k)) if hat else None
    powers = [(a, b) for a in range(5) for b in range(5 - a)]
    for lo in range(0, m, CHUNK):
        hi = min(lo + CHUNK, m)
        idx, dist = neighbours[lo:hi, :k], distances[lo:hi, :k]
        h = dist[:, -1] * (1.0 + 1e-6) + 1e-9
        w = tricube(dist / h[:, None])
        if weight is not None:
            w = w * weight[idx]
        x = (uv[idx, 0] - centres[lo:hi, 0, None]) / h[:, None]
        y = (uv[idx, 1] - centres[lo:hi, 1, None]) / h[:, None]
        xp = [np.ones_like(x), x, x * x, x * x * x, x * x * x * x]
        yp = [np.ones_like(y), y, y * y, y * y * y, y * y * y * y]
        mono = {(a, b): xp[a] * yp[b] for a, b in powers}
        moment = {key: (w * v).sum(axis=1) for key, v in mono.items()}
        moment2 = {key: (w * w * v).sum(axis=1) for key, v in mono.items()}
        t = QUADRIC[:terms]
        a = np.stack([np.stack([moment[(p[0] + q[0], p[1] + q[1])] for q in t], -1) for p in t], -2)
        b2 = np.stack([np.stack([moment2[(p[0] + q[0], p[1] + q[1])] for q in t], -1) for p in t], -2)
        rhs = np.stack([(w * mono[p] * values[idx]).sum(axis=1) for p in t], -1)
        a += RIDGE * np.trace(a, axis1=1, axis2=2)[:, None, None] * np.eye(terms)
        e0 = np.zeros((hi - lo, terms))
        e0[:, 0] = 1.0
        sol = cholesky_solve(a, np.stack([rhs, e0], axis=-1))
        coef[lo:hi] = sol[..., 0]
        z = sol[..., 1]  # a^-1 e0
        variance[lo:hi] = np.einsum("mi,mij,mj->m", z, b2, z)
        # the nearest point's share: its weight times its design row against a^-1 e0
        row = np.stack([mono[p][:, 0] for p in t], -1)
        leverage[lo:hi] = w[:, 0] * np.einsum("mi,mi->m", row, z)
        radius[lo:hi] = h
        if hat:
            hats[lo:hi] = w * sum(z[:, i, None] * mono[p] for i, p in enumerate(t))
    return LocalFits(coef, variance, leverage, radius, hats)
