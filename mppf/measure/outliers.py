"""Outliers and the form deviation: both judged against local planes through neighbouring deviations.

A point whose deviation differs from a robust local plane through its neighbours'
deviations by more than a robust threshold is an outlier (a stray return, dust); smooth
shape errors (a bump, springback) are not: their neighbours agree. The form deviation is
the plate's deviation with the scanner's point noise averaged out by a local plane
through each point's nearest neighbours. Positions in the design plane, mm.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

OUTLIER_NEIGHBOURS = 16
"""Neighbours (in the design plane) whose median deviation a point is compared with."""

OUTLIER_SIGMAS = 6.0
"""A point is an outlier when it differs from its neighbours by more than this many robust sigmas."""

OUTLIER_FLOOR_MM = 0.5
"""... and by more than this (so that a noise-free scan has no outliers)."""

FORM_NEIGHBOURS = 12
"""Neighbours (the point included) of the local plane that gives the form deviation: the
plate's own deviation with the scanner's point noise averaged out (``Comparison.form_deviation_mm``)."""


def find_outliers(uv: np.ndarray, deviation: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Points whose deviation differs from a robust local plane through their neighbours'.

    For each point, a plane d = a + b u + c v is fitted to the deviations of its
    ``OUTLIER_NEIGHBOURS`` nearest neighbours (in the design plane, the point itself left
    out), reweighted twice to ignore neighbours that are outliers themselves. The
    differences from those planes have a robust sigma (1.4826 MAD); a point is an outlier
    beyond ``OUTLIER_SIGMAS`` sigma (and ``OUTLIER_FLOOR_MM``). The local plane follows
    smooth shape errors, even steep ones, so those are never flagged.
    """
    idx = np.flatnonzero(valid)
    out = np.zeros(deviation.shape[0], dtype=bool)
    if min(OUTLIER_NEIGHBOURS + 1, idx.size) < 8:
        return out
    dev = deviation[idx]
    diff = dev - local_plane(uv[idx], dev, OUTLIER_NEIGHBOURS, leave_out=True, robust_passes=3)
    sigma = 1.4826 * np.median(np.abs(diff - np.median(diff)))
    out[idx] = np.abs(diff) > max(OUTLIER_SIGMAS * sigma, OUTLIER_FLOOR_MM)
    return out


def local_plane(pts: np.ndarray, values: np.ndarray, k: int, *, leave_out: bool, robust_passes: int) -> np.ndarray:
    """Value at each point of a plane d = a + b u + c v fitted to its ``k`` nearest neighbours.

    Parameters
    ----------
    pts : (m, 2) float
        Positions (mm, design plane).
    values : (m,) float
        Deviations there.
    k : int
        Neighbours in each fit (the point itself not counted when ``leave_out``).
    leave_out : bool
        Leave the point itself out of its own fit (for outlier tests).
    robust_passes : int
        Passes of reweighting that drop neighbours beyond 3 local median deviations
        (1: plain least squares).

    Returns
    -------
    (m,) float
    """
    k = min(k + int(leave_out), pts.shape[0])
    _, nb = cKDTree(pts).query(pts, k=k)
    if leave_out:
        nb = nb[:, 1:]
    rel = pts[nb] - pts[:, None, :]                                   # (m, k, 2)
    scale = np.maximum(np.abs(rel).max(axis=(1, 2)), 1e-9)[:, None, None]
    design = np.concatenate([np.ones(rel.shape[:2] + (1,)), rel / scale], axis=2)  # (m, k, 3)
    near = values[nb]
    weight = np.ones_like(near)
    for _ in range(robust_passes):
        a = np.einsum("mki,mk,mkj->mij", design, weight, design) + 1e-9 * np.eye(3)
        b = np.einsum("mki,mk,mk->mi", design, weight, near)
        coef = np.linalg.solve(a, b[..., None])[..., 0]
        resid = near - np.einsum("mki,mi->mk", design, coef)
        spread = np.maximum(np.median(np.abs(resid), axis=1, keepdims=True), 1e-6)
        weight = (np.abs(resid) <= 3.0 * spread).astype(float)
    return coef[:, 0]


def form_deviation(uv: np.ndarray, deviation: np.ndarray, inlier: np.ndarray, measured_ok: np.ndarray,
                   in_margin: np.ndarray) -> np.ndarray:
    """The form deviation (n,) of the inliers and of the trim margin's usable points, NaN elsewhere.

    The inliers' values come from the inliers alone (the net plate: the form statistics);
    the margin points' from all usable points, net and margin (for maps only).

    Parameters
    ----------
    uv : (n, 2) float, mm
        Foot points in the design plane.
    deviation : (n,) float, mm
    inlier, measured_ok, in_margin : (n,) bool
        The statistics' points; every point that is neither outside nor an outlier; the
        points in the trim margin.
    """
    form = np.full(deviation.shape[0], np.nan)
    form[inlier] = local_plane(uv[inlier], deviation[inlier], FORM_NEIGHBOURS, leave_out=False, robust_passes=1)
    margin_ok = measured_ok & in_margin
    if margin_ok.any():  # for maps only: the net plate's form values above do not see the margin
        form_all = local_plane(uv[measured_ok], deviation[measured_ok], FORM_NEIGHBOURS, leave_out=False,
                               robust_passes=1)
        form[margin_ok] = form_all[in_margin[measured_ok]]
    return form
