"""Set-aside points: only where a scanner artefact is certain, and every one of them reported.

A scanner's stray returns (dust, reflections, mixed pixels) are single points that disagree
with a dense neighbourhood which agrees with itself. A dent is not: its points agree with
their neighbours, and on sparse data (a total station's few hundred points, 50 mm or more
apart) one point IS the dent. So a point is set aside only when all of these hold
(``docs/compare.md``, "Set-aside points"):

1. the scan is dense around it: at least :data:`MIN_NEIGHBOURS` other points within
   :data:`RADIUS_SPACINGS` local point spacings (of the points around it) beyond its nearest
   neighbour, and that spacing at most
   :data:`DENSE_SPACING_MM` (on sparser data nothing is ever set aside);
2. a robust local quadric (a plane at an edge, where a quadric would extrapolate) through
   those neighbours (the point left out) misses the point by
   more than :data:`SIGMAS` times the larger of the scan's noise and the neighbours' own
   scatter about that quadric (a smooth feature the quadric cannot follow scatters its
   neighbours as much as it misses the point: not set aside);
3. and by more than :data:`FLOOR_MM`.

Positions in the design plane, mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from mppf.core.defaults import MAD_SCALE
from mppf.measure.localfit import spatial_query

MIN_NEIGHBOURS = 12
"""Fewest neighbours within :data:`RADIUS_SPACINGS` local spacings of a point that may be set aside."""

RADIUS_SPACINGS = 4.0
"""The neighbourhood of the artefact test, in local point spacings (small against a plate's features)."""

DENSE_SPACING_MM = 35.0
"""Largest local point spacing at which a point may be set aside: sparser data are measurements, not scans."""

NEIGHBOURS = 24
"""Most neighbours of the local quadric of the artefact test."""

SIGMAS = 6.0
"""A point is an artefact when its quadric misses it by more than this many noise sigmas ..."""

FLOOR_MM = 1.0
"""... and by more than this."""



@dataclass(frozen=True, eq=False)
class SetAside:
    """The set-aside points of a comparison, as reported (``Comparison.set_aside``).

    Attributes
    ----------
    count : int
    max_abs_mm : float
        Their largest absolute deviation (0 when none).
    beyond_tolerance : int
        How many lie beyond the tolerance (any: the verdict is "needs review").
    worst_uv_mm : (2,) float or None
        Where the largest one is (design plane).
    worst_press_xy_mm : (2,) float or None
        The same in press coordinates (when the press pose is known).
    worst_punch : str or None
        The punch nearest to it (``mppf.measure.punches.punch_name``).
    spacing_mm : float
        The scan's median local point spacing.
    dense_fraction : float
        Share of the points dense enough to be tested at all.
    """

    count: int
    max_abs_mm: float
    beyond_tolerance: int
    worst_uv_mm: np.ndarray | None
    worst_press_xy_mm: np.ndarray | None
    worst_punch: str | None
    spacing_mm: float
    dense_fraction: float

    def to_dict(self) -> dict:
        """JSON-able summary."""
        as_list = lambda a: None if a is None else [float(v) for v in a]  # noqa: E731
        return {"count": self.count, "max_abs_mm": self.max_abs_mm, "beyond_tolerance": self.beyond_tolerance,
                "worst_uv_mm": as_list(self.worst_uv_mm), "worst_press_xy_mm": as_list(self.worst_press_xy_mm),
                "worst_punch": self.worst_punch, "spacing_mm": self.spacing_mm,
                "dense_fraction": self.dense_fraction}

    def describe(self, tolerance_mm: float) -> str:
        """One line for the notes and the headline."""
        if not self.count:
            return (f"set aside: none (point spacing {self.spacing_mm:.0f} mm; "
                    f"{100 * self.dense_fraction:.0f} % of the points dense enough to test for scanner artefacts)")
        where = f"at u, v = {self.worst_uv_mm[0]:.0f}, {self.worst_uv_mm[1]:.0f} mm"
        if self.worst_press_xy_mm is not None:
            where += f" (press x, y = {self.worst_press_xy_mm[0]:.0f}, {self.worst_press_xy_mm[1]:.0f} mm"
            where += f", near punch {self.worst_punch})" if self.worst_punch else ")"
        return (f"set aside as scanner artefacts: {self.count} point(s), largest |deviation| {self.max_abs_mm:.2f} mm "
                f"{where}; {self.beyond_tolerance} beyond the tolerance +-{tolerance_mm:g} mm")


def local_spacing_mm(dist: np.ndarray) -> np.ndarray:
    """Local point spacing (m,) mm from the sorted neighbour distances (m, k >= 13), the point first:
    the square root of the area per point within the 8th neighbour."""
    return dist[:, 8] * np.sqrt(np.pi / 8.0)


@dataclass(frozen=True, eq=False)
class ArtefactTest:
    """The result of :func:`find_outliers`: which points are artefacts, and how dense the scan was for the test."""

    mask: np.ndarray          # (n,) bool: certainly scanner artefacts
    dense_fraction: float     # share of the tested points dense enough to be tested at all
    spacing_mm: float         # median local point spacing
    tree: cKDTree | None = None  # the k-d tree of the tested points (design plane; None when too few to test)


def find_outliers(uv: np.ndarray, deviation: np.ndarray, valid: np.ndarray) -> ArtefactTest:
    """The points (``ArtefactTest.mask``) that are certainly scanner artefacts (see the module docstring).

    Parameters
    ----------
    uv : (n, 2) float, mm
        Foot points in the design plane.
    deviation : (n,) float, mm
    valid : (n,) bool
        Points that may be tested (foot point on the design).
    """
    idx = np.flatnonzero(valid)
    out = np.zeros(deviation.shape[0], dtype=bool)
    if idx.size <= NEIGHBOURS:
        return ArtefactTest(out, 0.0, float("nan"))
    pts, dev = uv[idx], deviation[idx]
    tree = cKDTree(pts)
    dist, nb = spatial_query(tree, pts, MIN_NEIGHBOURS + 1)
    dense = _dense(dist, nb)
    # a cheap screen: far from the median of the nearest neighbours (most points end here)
    jump = dev - np.median(dev[nb[:, 1:MIN_NEIGHBOURS + 1]], axis=1)
    noise = MAD_SCALE * float(np.median(np.abs(jump - np.median(jump))))
    rows = np.flatnonzero(dense & (np.abs(jump) > max(SIGMAS * noise, FLOOR_MM)))
    if rows.size:
        near, nb = spatial_query(tree, pts[rows], NEIGHBOURS + 1)
        miss, scatter = _quadric_miss(pts, dev, rows, nb[:, 1:], near[:, 1:])
        artefact = np.abs(miss) > np.maximum(SIGMAS * np.maximum(scatter, noise), FLOOR_MM)
        out[idx[rows[artefact]]] = True
    return ArtefactTest(out, float(dense.mean()), float(np.median(local_spacing_mm(dist))), tree)


def _dense(dist: np.ndarray, nb: np.ndarray) -> np.ndarray:
    """Points dense enough to be tested: enough neighbours within the radius, the spacing small.

    The spacing at a point is the median of its own and its neighbours' estimates, so that
    a point at an edge or a corner (whose own estimate reaches round the corner) takes the
    spacing of the scan around it.
    """
    spacing = np.median(local_spacing_mm(dist)[nb], axis=1)
    # the radius reaches past the nearest neighbour: a stray point thrown off the plate's edge is still tested
    reach = RADIUS_SPACINGS * spacing + dist[:, 1]
    return (dist[:, MIN_NEIGHBOURS] <= reach) & (spacing <= DENSE_SPACING_MM)


def _quadric_miss(pts, dev, rows, nb, dist) -> tuple[np.ndarray, np.ndarray]:
    """(miss, scatter) of the points ``rows``: the deviation minus a robust quadric through their neighbours
    (within :data:`RADIUS_SPACINGS` spacings, the point left out), and the neighbours' robust scatter about it."""
    spacing = local_spacing_mm(np.column_stack([np.zeros(rows.size), dist]))
    use = (dist <= RADIUS_SPACINGS * spacing[:, None]).astype(float)
    rel = (pts[nb] - pts[rows][:, None, :]) / np.maximum(dist[:, -1], 1e-9)[:, None, None]
    x, y = rel[..., 0], rel[..., 1]
    # a quadric where the neighbours surround the point, a plane where it would be extrapolated (an edge)
    surrounded = (np.hypot(x.mean(axis=1), y.mean(axis=1)) < 1.0 / 3.0)[:, None].astype(float)
    design = np.stack([np.ones_like(x), x, y, surrounded * x * x, surrounded * x * y, surrounded * y * y], axis=-1)
    near = dev[nb]
    weight = use
    for _ in range(3):  # reweighted: neighbours that are artefacts themselves drop out
        a = np.einsum("mki,mk,mkj->mij", design, weight, design) + 1e-9 * np.eye(6)
        b = np.einsum("mki,mk,mk->mi", design, weight, near)
        coef = np.linalg.solve(a, b[..., None])[..., 0]
        resid = near - np.einsum("mki,mi->mk", design, coef)
        spread = np.maximum(_weighted_median_abs(resid, use), 1e-6)
        weight = use * (np.abs(resid) <= 4.0 * MAD_SCALE * spread[:, None])
    scatter = MAD_SCALE * _weighted_median_abs(resid, use)
    return dev[rows] - coef[:, 0], scatter


def _weighted_median_abs(resid: np.ndarray, use: np.ndarray) -> np.ndarray:
    """Median (m,) of ``|resid|`` over the entries with ``use`` 1 (each row has some)."""
    masked = np.where(use > 0, np.abs(resid), np.nan)
    return np.nanmedian(masked, axis=1)
