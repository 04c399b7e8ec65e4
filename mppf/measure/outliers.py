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

**Cleared by a rescan** (:func:`clear_by_rescans`; the union of several scans of one plate in one frame,
each point knowing its scan): a set-aside point beyond the tolerance is *cleared* when another scan
measured the same spot within the tolerance: at least :data:`CLEAR_MIN_POINTS` of its points that are
not set aside lie within :data:`CLEAR_RADIUS_SPACINGS` of its local point spacings (at least
:data:`CLEAR_RADIUS_FLOOR_MM`) of the point, all within the tolerance. Re-measurement is the proof
that it was an artefact. It is *confirmed* instead when another scan has a point within
:data:`CONFIRM_RADIUS_SPACINGS` spacings beyond the tolerance on the same side, within
:data:`CONFIRM_FRACTION` of its deviation (measured so twice: a real defect, or two artefacts at one
spot): never cleared (it keeps the verdict from "in tolerance" and a person looks). Two artefacts meet
by chance often enough in dense scans (1 % spikes: about one meeting per cycle and rescan) that one
more test is made: a confirmation needs that the other scan did not also measure the surface plainly
(within the tolerance) nearer the point than a flank of slope :data:`MAX_FLANK_SLOPE` would allow;
such a wall is no feature of a formed plate, so its agreeing point is an artefact of its own. Any scan
of the union may show the wall (the loop gives a confirmed spot another look: a rescan); no scan can
show one beside a real dent whose flanks are less steep, so the extra looks never clear a defect. With
one scan nothing is cleared or confirmed: issue 13's rule holds exactly.
"""

from __future__ import annotations

from dataclasses import dataclass, field

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

CLEAR_MIN_POINTS = 3
"""Fewest points of another scan, within the tolerance, that clear a set-aside point beyond it."""

CLEAR_RADIUS_SPACINGS = 2.0
"""Their radius about the point, in the other scan's local point spacings ..."""

CLEAR_RADIUS_FLOOR_MM = 5.0
"""... and at least this (mm)."""

CONFIRM_RADIUS_SPACINGS = 1.0
"""Another scan's point within this many of its local spacings (at least :data:`CLEAR_RADIUS_FLOOR_MM`) ..."""

CONFIRM_FRACTION = 0.3
"""... beyond the tolerance on the same side, within this share of the deviation, confirms it ..."""

MAX_FLANK_SLOPE = 2.0
"""... unless a scan (other than the point's own) measured the surface within the tolerance (a point not set
aside) so near the point, or near the agreeing point, that the deviation would have to change faster than this
per mm between them (a 63 degree flank: no dent of a formed plate is that steep; the narrowest dent of the tests,
8 mm deep, sigma 4 mm, has flanks of 1.2 at most): then the agreeing point is an artefact of its own at the same
spot, and the point is not confirmed. The two agreeing measurements themselves must not differ by more than
this slope times their distance apart, plus :data:`PAIR_NOISE_MM`."""

PAIR_NOISE_MM = 1.5
"""What two measurements of one spot may differ by beyond the flank between them (mm): 3 sigma of the difference
of two scans' noise of 0.35 mm each."""



@dataclass(frozen=True, eq=False)
class SetAside:
    """The set-aside points of a comparison, as reported (``Comparison.set_aside``).

    Attributes
    ----------
    count : int
    max_abs_mm : float
        Their largest absolute deviation (0 when none).
    beyond_tolerance : int
        How many lie beyond the tolerance and are not cleared by a rescan (any: the verdict is
        "needs review").
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
    cleared : int
        Set-aside points beyond the tolerance that another scan measured within it (:func:`clear_by_rescans`):
        still reported, they no longer make the verdict "needs review".
    cleared_by : dict
        ``{scan number: how many it cleared}`` (1: the first rescan; 0: the first scan cleared a rescan's).
    confirmed : int
        Set-aside points beyond the tolerance another scan confirmed (measured so twice): never cleared,
        counted in ``beyond_tolerance``.
    """

    count: int
    max_abs_mm: float
    beyond_tolerance: int
    worst_uv_mm: np.ndarray | None
    worst_press_xy_mm: np.ndarray | None
    worst_punch: str | None
    spacing_mm: float
    dense_fraction: float
    cleared: int = 0
    cleared_by: dict = field(default_factory=dict)
    confirmed: int = 0

    def to_dict(self) -> dict:
        """JSON-able summary."""
        as_list = lambda a: None if a is None else [float(v) for v in a]  # noqa: E731
        return {"count": self.count, "max_abs_mm": self.max_abs_mm, "beyond_tolerance": self.beyond_tolerance,
                "worst_uv_mm": as_list(self.worst_uv_mm), "worst_press_xy_mm": as_list(self.worst_press_xy_mm),
                "worst_punch": self.worst_punch, "spacing_mm": self.spacing_mm,
                "dense_fraction": self.dense_fraction, "cleared": self.cleared,
                "cleared_by": {str(k): int(v) for k, v in self.cleared_by.items()}, "confirmed": self.confirmed}

    def describe(self, tolerance_mm: float) -> str:
        """One line for the notes and the headline."""
        confirmed = (f"; {self.confirmed} of them confirmed by another scan (measured so twice: the plate?)"
                     if self.confirmed else "")
        if not self.count:
            return (f"set aside: none (point spacing {self.spacing_mm:.0f} mm; "
                    f"{100 * self.dense_fraction:.0f} % of the points dense enough to test for scanner artefacts)"
                    + confirmed)
        where = f"at u, v = {self.worst_uv_mm[0]:.0f}, {self.worst_uv_mm[1]:.0f} mm"
        if self.worst_press_xy_mm is not None:
            where += f" (press x, y = {self.worst_press_xy_mm[0]:.0f}, {self.worst_press_xy_mm[1]:.0f} mm"
            where += f", near punch {self.worst_punch})" if self.worst_punch else ")"
        text = (f"set aside as scanner artefacts: {self.count} point(s), largest |deviation| {self.max_abs_mm:.2f} mm "
                f"{where}; {self.beyond_tolerance} beyond the tolerance +-{tolerance_mm:g} mm")
        if self.cleared:
            text += f" not cleared, {self.cleared} beyond it {self.cleared_text()}"
        return text + confirmed

    def cleared_text(self) -> str:
        """"cleared by rescan 1 (80), the first scan (37)": which scans re-measured them within the tolerance."""
        names = [("the first scan" if int(k) == 0 else f"rescan {int(k)}", v)
                 for k, v in sorted(self.cleared_by.items())]
        return "cleared by " + ", ".join(f"{name} ({count})" for name, count in names)


@dataclass(frozen=True, eq=False)
class Clearing:
    """The result of :func:`clear_by_rescans` (all (n,) arrays).

    Attributes
    ----------
    cleared : (n,) bool
        Set-aside points beyond the tolerance that another scan measured within it.
    cleared_by : (n,) int
        The scan that cleared each (the first of them; -1 where not cleared).
    confirmed : (n,) bool
        Set-aside points beyond the tolerance another scan confirms (never cleared).
    """

    cleared: np.ndarray
    cleared_by: np.ndarray
    confirmed: np.ndarray


def _scan_parts(uv: np.ndarray, valid: np.ndarray, scan_index: np.ndarray, scans: np.ndarray) -> dict:
    """``{scan: (its measured points (k,) int, their k-d tree, clear radius mm, confirm radius mm)}``, the radii from
    the scan's own point spacing; a scan with too few points is left out."""
    parts = {}
    for scan in scans:
        own = np.flatnonzero(valid & (scan_index == scan))
        if own.size > MIN_NEIGHBOURS:
            tree = cKDTree(uv[own])
            spacing = float(np.median(local_spacing_mm(spatial_query(tree, uv[own], MIN_NEIGHBOURS + 1)[0])))
            parts[scan] = (own, tree, max(CLEAR_RADIUS_SPACINGS * spacing, CLEAR_RADIUS_FLOOR_MM),
                           max(CONFIRM_RADIUS_SPACINGS * spacing, CLEAR_RADIUS_FLOOR_MM))
    return parts


def clear_by_rescans(uv: np.ndarray, deviation: np.ndarray, set_aside: np.ndarray, valid: np.ndarray,
                     scan_index: np.ndarray, tolerance_mm: float) -> Clearing:
    """Which set-aside points beyond the tolerance other scans clear or confirm (see the module docstring).

    Parameters
    ----------
    uv : (n, 2) float, mm
        Foot points in the design plane (the union of the scans).
    deviation : (n,) float, mm
    set_aside : (n,) bool
        The points set aside (:func:`find_outliers`).
    valid : (n,) bool
        Points measured (foot point on the design).
    scan_index : (n,) int
        The scan each point came from (0: the first scan, K: its K-th rescan).
    tolerance_mm : float
    """
    n = deviation.shape[0]
    cleared, confirmed = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    cleared_by = np.full(n, -1, dtype=int)
    beyond = set_aside & valid & (np.abs(np.nan_to_num(deviation)) > tolerance_mm)
    scans = np.unique(scan_index[valid])
    if scans.size < 2 or not beyond.any():
        return Clearing(cleared, cleared_by, confirmed)
    parts = _scan_parts(uv, valid, scan_index, scans)

    def walled(point: int) -> bool:
        """Whether a scan other than the point's own measured a plain surface (within the tolerance, not set aside)
        so near it that the deviation would change faster than MAX_FLANK_SLOPE between them: no plate feature is
        there, whatever another scan agreed."""
        for scan, (own, tree, radius, _) in parts.items():
            if scan == scan_index[point]:
                continue
            near = own[np.asarray(tree.query_ball_point(uv[point], radius), dtype=int)]
            plain = ~set_aside[near] & (np.abs(deviation[near]) <= tolerance_mm)
            apart = np.linalg.norm(uv[near] - uv[point], axis=1)
            if np.any(plain & (np.abs(deviation[point] - deviation[near]) > MAX_FLANK_SLOPE * apart)):
                return True
        return False

    for scan, (own, tree, radius, close) in parts.items():
        rows = np.flatnonzero(beyond & (scan_index != scan))
        for row, near in zip(rows, tree.query_ball_point(uv[rows], radius) if rows.size else []):
            near = own[np.asarray(near, dtype=int)]
            d, mine = deviation[near], deviation[row]
            apart = np.linalg.norm(uv[near] - uv[row], axis=1)
            # alike: beyond the tolerance on the same side, within CONFIRM_FRACTION, and no steeper between the two
            # than a plate's flank (two spikes 0.7 mm apart, 30 and 23 mm high, are no one feature)
            alike = near[(apart <= close) & (np.abs(d) > tolerance_mm) & (np.sign(d) == np.sign(mine))
                         & (np.abs(d - mine) <= np.minimum(CONFIRM_FRACTION * abs(mine),
                                                           MAX_FLANK_SLOPE * apart + PAIR_NOISE_MM))]
            # measured alike twice confirms, unless a scan saw a plain surface beside either excursion, nearer than
            # a plate's flank allows (then the two are artefacts at one spot by chance; a third look may show it)
            if alike.size and not confirmed[row] and not walled(row):
                confirmed[row] = any(not walled(other) for other in alike)
            if np.sum(~set_aside[near] & (np.abs(d) <= tolerance_mm)) >= CLEAR_MIN_POINTS and cleared_by[row] < 0:
                cleared_by[row] = scan
    cleared = beyond & (cleared_by >= 0) & ~confirmed
    return Clearing(cleared, np.where(cleared, cleared_by, -1), confirmed)


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


def find_outliers_by_scan(uv: np.ndarray, deviation: np.ndarray, valid: np.ndarray,
                          scan_index: np.ndarray) -> ArtefactTest:
    """:func:`find_outliers` of each scan of a union on its own (a scan's artefact is judged by that scan's
    neighbours: another scan's points, a little offset, would blur the test), the masks joined; the dense
    share of the first scan, the spacing and the k-d tree of the union's tested points."""
    scans = np.unique(scan_index[valid])
    if scans.size < 2:
        return find_outliers(uv, deviation, valid)
    out = np.zeros(deviation.shape[0], dtype=bool)
    first = None
    for scan in scans:
        test = find_outliers(uv, deviation, valid & (scan_index == scan))
        out |= test.mask
        first = test if first is None else first
    tree = cKDTree(uv[valid])
    spacing = float(np.median(local_spacing_mm(spatial_query(tree, uv[valid], MIN_NEIGHBOURS + 1)[0])))
    return ArtefactTest(out, first.dense_fraction, spacing, tree)


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
    # a robust start: neighbours far from the neighbours' median are left out of the first fit. Started from all of
    # them, a neighbouring artefact at the rim of the neighbourhood (where the quadric terms have most leverage)
    # bends the first quadric onto itself; the scatter it leaves then hides the point tested (0.1 % of 1 % spikes)
    centre = _weighted_median(near, use)
    spread = np.maximum(_weighted_median_abs(near - centre[:, None], use), 1e-6)
    weight = use * (np.abs(near - centre[:, None]) <= np.maximum(4.0 * MAD_SCALE * spread, FLOOR_MM)[:, None])
    for _ in range(3):  # reweighted: neighbours that are artefacts themselves drop out
        a = np.einsum("mki,mk,mkj->mij", design, weight, design) + 1e-9 * np.eye(6)
        b = np.einsum("mki,mk,mk->mi", design, weight, near)
        coef = np.linalg.solve(a, b[..., None])[..., 0]
        resid = near - np.einsum("mki,mi->mk", design, coef)
        spread = np.maximum(_weighted_median_abs(resid, use), 1e-6)
        weight = use * (np.abs(resid) <= 4.0 * MAD_SCALE * spread[:, None])
    scatter = MAD_SCALE * _weighted_median_abs(resid, use)
    return dev[rows] - coef[:, 0], scatter


def _weighted_median(values: np.ndarray, use: np.ndarray) -> np.ndarray:
    """Median (m,) of ``values`` (m, k) over the entries with ``use`` 1 (each row has some)."""
    return np.nanmedian(np.where(use > 0, values, np.nan), axis=1)


def _weighted_median_abs(resid: np.ndarray, use: np.ndarray) -> np.ndarray:
    """Median (m,) of ``|resid|`` over the entries with ``use`` 1 (each row has some)."""
    return _weighted_median(np.abs(resid), use)
