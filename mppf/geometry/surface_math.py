"""Arithmetic shared by the plate surfaces: argument checks, monomial powers, unit normals, residuals.

Used by :mod:`mppf.geometry.polynomial`, :mod:`mppf.geometry.spline` and the foot-point
search (:mod:`mppf.geometry.localize`); lengths in mm.
"""

from __future__ import annotations

import numpy as np

from mppf.core.errors import InputError

Bounds = tuple[tuple[float, float], tuple[float, float]]
"""((umin, umax), (vmin, vmax)) of the fitted points, mm."""


def uv_arrays(u, v) -> tuple[np.ndarray, np.ndarray]:
    """``u`` and ``v`` as float arrays broadcast to one shape."""
    u_arr, v_arr = np.broadcast_arrays(np.asarray(u, dtype=float), np.asarray(v, dtype=float))
    return u_arr, v_arr


def unit_normals(zu, zv) -> np.ndarray:
    """Unit normals (..., 3) of z = D(u, v) from its slopes, pointing to +w."""
    zu = np.asarray(zu, dtype=float)
    zv = np.asarray(zv, dtype=float)
    n = np.stack([-zu, -zv, np.ones_like(zu)], axis=-1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def residual_stats(residual: np.ndarray) -> tuple[float, float]:
    """(RMS, largest absolute value) of fit residuals, mm."""
    return float(np.sqrt(np.mean(residual**2))), float(np.max(np.abs(residual)))


def powers(x: np.ndarray, k: int, order: int = 2) -> list[np.ndarray]:
    """[x^i, d/dx x^i, d2/dx2 x^i][:order + 1] for i = 0..k, each (k+1, n) (rows contiguous)."""
    p = np.empty((k + 1, x.size))
    p[0] = 1.0
    for i in range(1, k + 1):
        np.multiply(p[i - 1], x, out=p[i])
    out = [p]
    for d in range(1, order + 1):
        dp = np.zeros_like(p)
        for i in range(d, k + 1):
            np.multiply(p[i - d], float(np.prod(np.arange(i - d + 1, i + 1))), out=dp[i])
        out.append(dp)
    return out


def check_uvz(u, v, z) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``u, v, z`` as finite 1-D float arrays of one length (the columns of local points).

    Raises
    ------
    InputError
        Other shapes or NaN / infinite values.
    """
    arrays = [np.asarray(x, dtype=float) for x in (u, v, z)]
    if any(a.ndim != 1 for a in arrays) or len({a.shape for a in arrays}) != 1:
        raise InputError(
            f"u, v, z must be 1-D arrays of one length, got shapes {[a.shape for a in arrays]}",
            hint="pass the columns of the local points separately",
        )
    if not all(np.all(np.isfinite(a)) for a in arrays):
        raise InputError("u, v, z contain NaN or infinite values")
    return arrays[0], arrays[1], arrays[2]


def bounds_of(u: np.ndarray, v: np.ndarray) -> Bounds:
    """The (u, v) range of points."""
    return (float(u.min()), float(u.max())), (float(v.min()), float(v.max()))
