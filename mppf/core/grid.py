"""Height fields on regular grids and scattered values: planes, curvature tensors, fills.

The one place in mppf for: removing a best-fit plane, the curvature tensor (small-slope
Hessian) of a grid and its principal decomposition, integrating a curvature field back to
heights, the thin-plate-spline fill of scattered values, and neighbour differences on
the punch grid. Grids are ``(ny, nx)`` arrays, the first axis along y (spacing ``hy``),
the second along x (spacing ``hx``); lengths in mm, curvatures in 1/mm.
"""

from __future__ import annotations

import functools

import numpy as np

ROBUST_PASSES = 3
"""Reweighting passes of :func:`best_plane` with ``robust=True``."""


def best_plane(x, y, z, weight=None, *, robust: bool = False) -> np.ndarray:
    """Coefficients ``(a, b, c)`` of the plane ``z ~ a + b x + c y`` (least squares).

    Parameters
    ----------
    x, y, z : (n,) float
        Positions and values; non-finite values of ``z`` are left out.
    weight : (n,) float >= 0, optional
        Weight of each point (default 1).
    robust : bool
        Refit twice without the points beyond 3 robust sigma (1.4826 MAD) of the residual.

    Returns
    -------
    (3,) float
    """
    x, y, z = (np.asarray(a, dtype=float).ravel() for a in (x, y, z))
    w = np.ones_like(z) if weight is None else np.asarray(weight, dtype=float).ravel()
    design = np.column_stack([np.ones_like(x), x, y])
    keep = np.isfinite(z)
    coef = np.zeros(3)
    for _ in range(ROBUST_PASSES if robust else 1):
        if keep.sum() < 3:
            break
        coef, *_ = np.linalg.lstsq(design[keep] * w[keep, None], z[keep] * w[keep], rcond=None)
        if robust:
            resid = z - design @ coef
            mad = np.median(np.abs(resid[keep] - np.median(resid[keep])))
            keep = np.isfinite(z) & (np.abs(resid) <= max(3.0 * 1.4826 * mad, 1e-6))
    return coef


def plane_values(coef, x, y) -> np.ndarray:
    """The plane ``a + b x + c y`` at the positions (any shape)."""
    return coef[0] + coef[1] * np.asarray(x, dtype=float) + coef[2] * np.asarray(y, dtype=float)


def without_plane(x, y, z, mask=None, weight=None, *, robust: bool = False) -> np.ndarray:
    """``z`` minus its best-fit plane, fitted over ``mask`` (any shape; NaN stays NaN).

    Parameters
    ----------
    x, y, z : array_like, same shape
    mask : bool array of that shape, optional
        Points the plane is fitted to (default: every finite ``z``).
    weight : array of that shape, optional
    robust : bool
        See :func:`best_plane`.
    """
    z = np.asarray(z, dtype=float)
    sel = np.isfinite(z) if mask is None else (np.asarray(mask, dtype=bool) & np.isfinite(z))
    w = None if weight is None else np.asarray(weight, dtype=float)[sel]
    coef = best_plane(np.asarray(x, dtype=float)[sel], np.asarray(y, dtype=float)[sel], z[sel], w, robust=robust)
    return z - plane_values(coef, x, y)


def hessian(z, hx: float, hy: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Second derivatives ``(zxx, zxy, zyy)`` of a grid by central differences.

    Parameters
    ----------
    z : (ny, nx) float
    hx, hy : float
        Spacings along x (second axis) and y (first axis), mm.

    Returns
    -------
    zxx, zxy, zyy : (ny, nx) float, 1/mm
        The small-slope curvature tensor.
    """
    zy, zx = np.gradient(z, hy, hx)
    zxx = np.gradient(zx, hx, axis=1)
    zyy = np.gradient(zy, hy, axis=0)
    zxy = 0.5 * (np.gradient(zx, hy, axis=0) + np.gradient(zy, hx, axis=1))
    return zxx, zxy, zyy


def tensor(kxx, kxy, kyy) -> np.ndarray:
    """Stack ``(kxx, kxy, kyy)`` of any shape into symmetric ``(..., 2, 2)`` tensors."""
    return np.stack([np.stack([kxx, kxy], -1), np.stack([kxy, kyy], -1)], -2)


def principal(kxx, kxy, kyy) -> tuple[np.ndarray, np.ndarray]:
    """Principal curvatures and directions of a curvature tensor field.

    Returns
    -------
    kappa : (..., 2) float
        Eigenvalues in ascending order.
    vectors : (..., 2, 2) float
        Unit eigenvectors as columns (``vectors[..., :, i]`` belongs to ``kappa[..., i]``).
    """
    return np.linalg.eigh(tensor(kxx, kxy, kyy))


def from_principal(kappa, vectors) -> np.ndarray:
    """The tensor ``V diag(kappa) V^T`` back from principal values and directions, ``(..., 2, 2)``."""
    return np.einsum("...ik,...k,...jk->...ij", vectors, kappa, vectors)


def _second_difference(n: int, h: float):
    """(n, n) second-difference operator; one-sided at the ends (rows copy the neighbours)."""
    from scipy import sparse

    d = sparse.diags([np.ones(n - 1), np.full(n, -2.0), np.ones(n - 1)], [-1, 0, 1], format="lil")
    d[0, :3] = [1.0, -2.0, 1.0]
    d[n - 1, n - 3:] = [1.0, -2.0, 1.0]
    return d.tocsr() / (h * h)


def _first_difference(n: int, h: float):
    """(n, n) central first-difference operator, one-sided at the ends."""
    from scipy import sparse

    d = sparse.diags([-np.ones(n - 1), np.ones(n - 1)], [-1, 1], format="lil") * 0.5
    d[0, :2] = [-1.0, 1.0]
    d[n - 1, n - 2:] = [-1.0, 1.0]
    return d.tocsr() / h


def integrate_hessian(hxx, hxy, hyy, hx: float, hy: float) -> np.ndarray:
    """Heights w whose second derivatives best match the given fields (least squares).

    Parameters
    ----------
    hxx, hxy, hyy : (ny, nx) float
        Wanted second derivatives on a regular grid (first axis y, spacing ``hy``;
        second axis x, spacing ``hx``), 1/mm.
    hx, hy : float
        Grid spacings, mm.

    Returns
    -------
    (ny, nx) float
        Heights, mm, up to a plane a + b x + c y (fixed by the caller; a tiny Tikhonov
        term keeps the system regular).
    """
    hxx = np.asarray(hxx, dtype=float)
    ny, nx = hxx.shape
    a, factors = _hessian_system(ny, nx, float(hx), float(hy))
    scale = max(hx, hy) ** 2
    b = np.concatenate([hxx.ravel() * scale, np.asarray(hyy, dtype=float).ravel() * scale,
                        np.sqrt(2.0) * np.asarray(hxy, dtype=float).ravel() * scale, np.zeros(nx * ny)])
    return factors.solve(a.T @ b).reshape(ny, nx)


@functools.lru_cache(maxsize=8)
def _hessian_system(ny: int, nx: int, hx: float, hy: float):
    """The least-squares operator of :func:`integrate_hessian` on a grid and the LU factors of its
    normal matrix; cached, since the plate model and the corrections integrate on the same grid
    again and again (the factorisation is most of the cost)."""
    from scipy import sparse
    from scipy.sparse.linalg import splu

    ix, iy = sparse.identity(nx), sparse.identity(ny)
    dxx = sparse.kron(iy, _second_difference(nx, hx))
    dyy = sparse.kron(_second_difference(ny, hy), ix)
    dxy = sparse.kron(_first_difference(ny, hy), _first_difference(nx, hx))
    scale = max(hx, hy) ** 2
    reg = sparse.identity(nx * ny) * 1e-6
    a = sparse.vstack([dxx * scale, dyy * scale, np.sqrt(2.0) * dxy * scale, reg]).tocsr()
    return a, splu((a.T @ a).tocsc())


def tps_fill(known_xy, values, query_xy, smoothing: float = 0.0) -> np.ndarray:
    """Values at ``query_xy`` of a thin-plate spline through scattered values.

    Parameters
    ----------
    known_xy : (m, 2) float, mm
        Where the values are known (m >= 3, not all on one line).
    values : (m,) float
    query_xy : (q, 2) float, mm
    smoothing : float
        Smoothing of the spline (0: interpolating; see scipy's ``RBFInterpolator``).

    Returns
    -------
    (q,) float
    """
    from scipy.interpolate import RBFInterpolator

    spline = RBFInterpolator(np.asarray(known_xy, dtype=float), np.asarray(values, dtype=float),
                             kernel="thin_plate_spline", smoothing=smoothing)
    return spline(np.asarray(query_xy, dtype=float))


def neighbour_differences(values_mm, active):
    """Differences between row and column neighbours that are both active.

    Parameters
    ----------
    values_mm : (rows, cols) float
    active : (rows, cols) bool

    Returns
    -------
    list of (diff (k,) float, first (k, 2) int, second (k, 2) int)
        One entry for row neighbours (along x) and one for column neighbours (along y).
    """
    values_mm = np.asarray(values_mm, dtype=float)
    active = np.asarray(active, dtype=bool)
    out = []
    for axis in (1, 0):
        a = np.swapaxes(values_mm, 0, axis)
        m = np.swapaxes(active, 0, axis)
        both = m[1:] & m[:-1]
        idx = np.argwhere(both)
        diff = a[1:][both] - a[:-1][both]
        first = idx.copy()
        second = idx.copy()
        second[:, 0] += 1
        if axis == 1:  # swapped back: (col, row) -> (row, col)
            first, second = first[:, ::-1], second[:, ::-1]
        out.append((diff, first, second))
    return out


def largest_neighbour_difference(values_mm, active) -> float:
    """Largest |difference| between neighbouring active punches (mm; 0 when none)."""
    diffs = [np.abs(d) for d, _, _ in neighbour_differences(values_mm, active)]
    return float(max((d.max() for d in diffs if d.size), default=0.0))


def neighbour_mean(values, mask) -> np.ndarray:
    """Mean of the 4-neighbours within ``mask`` (the value itself where it has none)."""
    values = np.asarray(values, dtype=float)
    total = np.zeros_like(values)
    count = np.zeros_like(values)
    padded = np.pad(np.where(mask, values, 0.0), 1)
    pmask = np.pad(np.asarray(mask).astype(float), 1)
    rows, cols = values.shape
    for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        total += padded[1 + dr:1 + dr + rows, 1 + dc:1 + dc + cols]
        count += pmask[1 + dr:1 + dr + rows, 1 + dc:1 + dc + cols]
    return np.where(count > 0, total / np.maximum(count, 1.0), values)
