"""The form deviation: the plate's deviation with the scanner's point noise averaged out, as far as the data allow.

A scan's single points carry noise (0.3 mm gives extremes near +-1.2 mm over 15,000
points); a steel plate has no bumps of 1 mm that are 20 mm wide. But a real dent must keep
its depth. So the smoothing scale is chosen point by point from the point spacing and the
noise (``docs/compare.md``, step 6):

1. Local quadric fits (:mod:`mppf.measure.localfit`, LOESS with tricube weights) over the
   nearest :data:`SCALES` points (about 1.8, 2.5 and 3.6 point spacings in radius).
2. The noise ``sigma`` of the deviations: the scatter of the points about their k = 20 fits,
   each residual divided by its own standard deviation (robust: 1.4826 x median).
3. Intersection of confidence intervals (ICI): a point takes the widest fit whose interval
   ``value +- GAMMA sigma sqrt(v)`` still meets those of all narrower fits: on a smooth
   plate the widest (noise cut about 3 times), at a dent's flank or peak the narrowest that
   is not biased by its curvature.
4. Extremes between points: at the largest local extrema of the form field the fits are
   centred again on the fitted peak (twice) and the ICI repeated there, so a dent whose
   deepest point falls between sparse points is not reported shallower.

On sparse data (few hundred points, 50 mm or more apart) the fits span few points and stay
close to the measured values; on dense scans they average the noise. Positions in the
design plane, mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from mppf.core.defaults import MAD_SCALE
from mppf.measure.localfit import LocalFits, fit, spatial_query
from mppf.measure.localfit import fits as shared_fits

FIELD = ((10, 6), (20, 6), (40, 6), (40, 3))
"""(points, terms) of the local fits the form deviation chooses from, narrowest first: quadrics (6 terms),
then a plane (3) over the widest neighbourhood (the least noise on a smooth plate)."""

PEAK = FIELD
"""The same at the refined extremes."""

SCALES = tuple(k for k, _ in FIELD)
"""Points of the field's fits, narrowest first."""

GAMMA_RANGE = (3.0, 5.0)
"""A narrower fit that differs from a wider one by more than ``gamma`` standard deviations of their difference
vetoes the wider one (Lepski's rule); over the whole plate ``gamma = sqrt(2 ln n)`` within this range (n
points), so that noise alone makes no feature anywhere."""

GAMMA = 3.0
"""The default ``gamma`` of :func:`smooth` (the whole plate's is from :data:`GAMMA_RANGE`)."""

CHUNK = 20000
"""Centres whose fits are held at once."""

PEAK_GAMMA = 2.0
"""The same at the refined extremes (few, so fewer false alarms to guard against)."""

PEAKS = 24
"""Largest local extrema of the form field that are refined between points."""

NOISE_SAMPLE = 5000
"""Points (a seeded sample) whose residuals give the noise."""



@dataclass(frozen=True, eq=False)
class FormField:
    """The form deviation of a set of points.

    Attributes
    ----------
    values : (m,) float, mm
        The form deviation at the centres.
    scale : (m,) int
        The index in :data:`SCALES` of the fit each centre took.
    peak_mm : float
        The signed form deviation of largest magnitude, extremes between points included.
    peak_uv_mm : (2,) float
        Where it lies.
    noise_mm : float
        The deviations' noise (point scatter about the local fits).
    spacing_mm : float
        The median point spacing (square root of the area per point).
    radius_mm : (len(SCALES),) float
        Median radius of the fits of each scale.
    """

    values: np.ndarray
    scale: np.ndarray
    peak_mm: float
    peak_uv_mm: np.ndarray
    noise_mm: float
    spacing_mm: float
    radius_mm: np.ndarray

    def describe(self) -> str:
        """The smoothing stated in words (for the output)."""
        used = np.bincount(self.scale, minlength=len(SCALES)) / max(self.scale.size, 1)
        shares = ", ".join(f"{k} points (radius {r:.0f} mm) {100 * u:.0f} %"
                           for k, r, u in zip(SCALES, self.radius_mm, used))
        return (f"form deviation: smoothing scale from the point spacing {self.spacing_mm:.1f} mm and the noise "
                f"{self.noise_mm:.2f} mm: local quadric fits, the widest the data allow point by point (Lepski/ICI): "
                f"{shares}; form max {abs(self.peak_mm):.2f} mm at u, v = {self.peak_uv_mm[0]:.0f}, "
                f"{self.peak_uv_mm[1]:.0f} mm")

    def to_dict(self) -> dict:
        """JSON-able summary."""
        used = np.bincount(self.scale, minlength=len(SCALES)) / max(self.scale.size, 1)
        return {"spacing_mm": self.spacing_mm, "noise_mm": self.noise_mm, "neighbours": list(SCALES),
                "radius_mm": [float(r) for r in self.radius_mm], "share": [float(u) for u in used],
                "peak_mm": self.peak_mm, "peak_uv_mm": [float(v) for v in self.peak_uv_mm]}


def noise_mm(uv: np.ndarray, values: np.ndarray, tree: cKDTree) -> float:
    """The deviations' noise: their scatter about their own k = 20 quadric fits (robust), mm."""
    k = min(SCALES[1], uv.shape[0])
    sample = np.arange(uv.shape[0])
    if sample.size > NOISE_SAMPLE:
        sample = np.sort(np.random.default_rng(0).choice(sample.size, NOISE_SAMPLE, replace=False))
    dist, nb = spatial_query(tree, uv[sample], k)
    fits = fit(uv, values, uv[sample], (dist, nb), k)
    spread = np.sqrt(np.maximum(1.0 - 2.0 * fits.leverage + fits.variance, 1e-3))
    return float(MAD_SCALE * np.median(np.abs(values[sample] - fits.value) / spread))


def _lepski(fits: list[LocalFits], sigma: float, gamma: float) -> tuple[np.ndarray, np.ndarray]:
    """(values, level index): the widest fit that every narrower fit agrees with.

    Fits ``i`` (narrower) and ``j`` agree when ``|f_i - f_j| <= gamma sigma sd_ij``, with
    ``sd_ij^2 = sum (hat_i - hat_j)^2`` the variance of their difference per unit noise
    variance (they share their nearest points, so they are correlated).
    """
    width = max(f.hat.shape[1] for f in fits)
    hats = [np.pad(f.hat, ((0, 0), (0, width - f.hat.shape[1]))) for f in fits]
    accepted = np.ones((len(fits), fits[0].value.size), dtype=bool)
    for j in range(1, len(fits)):
        for i in range(j):
            sd = np.sqrt(((hats[i] - hats[j]) ** 2).sum(axis=1))
            accepted[j] &= np.abs(fits[i].value - fits[j].value) <= gamma * sigma * sd + 1e-12
    level = len(fits) - 1 - np.argmax(accepted[::-1], axis=0)
    values = np.choose(level, [f.value for f in fits])
    return values, level


def smooth(uv: np.ndarray, values: np.ndarray, centres: np.ndarray, sigma: float, tree: cKDTree,
           gamma: float = GAMMA, levels=None, keep: bool = False) -> tuple[np.ndarray, np.ndarray, list]:
    """The form deviation at ``centres`` from the data (``uv``, ``values``).

    Returns (values (m,), level index (m,), fits): the fits of every level (with ``keep``) or
    their median radii (mm).
    """
    levels = FIELD if levels is None else levels
    ks = [min(k, uv.shape[0]) for k, _ in levels]
    dist, nb = spatial_query(tree, centres, max(ks))
    out, level = np.empty(centres.shape[0]), np.empty(centres.shape[0], dtype=int)
    kept, radius = [], []
    for lo in range(0, centres.shape[0], CHUNK):
        hi = min(lo + CHUNK, centres.shape[0])
        fits = _level_fits(uv, values, centres[lo:hi], nb[lo:hi], dist[lo:hi], ks, [t for _, t in levels])
        out[lo:hi], level[lo:hi] = _lepski(fits, sigma, gamma)
        kept.append(fits)
        radius.append([np.median(f.radius) for f in fits])
    if keep:
        return out, level, kept[0]
    return out, level, list(np.median(np.array(radius), axis=0))


def _level_fits(uv, values, centres, nb, dist, ks: list[int], terms: list[int]) -> list[LocalFits]:
    """The fits of every level (with their hat weights), in the order of the levels; levels over the same number
    of points share one neighbourhood (:func:`mppf.measure.localfit.fits`)."""
    out: list = [None] * len(ks)
    for k in dict.fromkeys(ks):
        mine = [i for i, kk in enumerate(ks) if kk == k]
        for i, f in zip(mine, shared_fits(uv, values, centres, (dist, nb), k, tuple(terms[i] for i in mine), hat=True)):
            out[i] = f
    return out


def _stationary(fits: LocalFits, rows: np.ndarray) -> np.ndarray:
    """Offsets (j, 2) mm from the centres to the stationary points of their quadrics (0 where not an extremum)."""
    c = fits.coef[rows]
    if c.shape[1] < 6:  # a plane has no extremum
        return np.zeros((rows.size, 2))
    hxx, hxy, hyy = 2 * c[:, 3], c[:, 4], 2 * c[:, 5]
    det = hxx * hyy - hxy**2
    ok = det > 1e-12 * (hxx**2 + hyy**2 + 1e-300)
    safe = np.where(ok, det, 1.0)
    x = -(hyy * c[:, 1] - hxy * c[:, 2]) / safe
    y = -(-hxy * c[:, 1] + hxx * c[:, 2]) / safe
    offset = np.column_stack([x, y]) * fits.radius[rows][:, None]
    return np.where(ok[:, None], offset, 0.0)


def _steps(fits: list[LocalFits], scale: np.ndarray) -> np.ndarray:
    """Offsets (j, 2) mm from each centre to the stationary point of the fit it took."""
    step = np.zeros((scale.size, 2))
    for j, f in enumerate(fits):
        mine = np.flatnonzero(scale == j)
        if mine.size:
            step[mine] = _stationary(f, mine)
    return step


def _surrounded(uv: np.ndarray, centres: np.ndarray, tree: cKDTree) -> np.ndarray:
    """Centres (j,) inside the data: their nearest points' centroid within a third of their radius (not at an edge)."""
    dist, nb = tree.query(centres, k=min(PEAK[1][0], uv.shape[0]))
    offset = np.linalg.norm(uv[nb].mean(axis=1) - centres, axis=1)
    return offset < dist[:, -1] / 3.0


def _refine_peaks(uv, values, form, level, sigma, tree, spacing) -> tuple[float, np.ndarray]:
    """The signed extreme of the form field and where: its largest local extrema that are features (the field
    took a narrower fit than the widest there) re-centred on their peaks."""
    _, nb = tree.query(uv, k=min(10, uv.shape[0]))
    feature = level < len(FIELD) - 1
    rows = np.flatnonzero((np.abs(form) >= np.abs(form[nb]).max(axis=1)) & feature)
    rows = rows[np.argsort(-np.abs(form[rows]))[:PEAKS]]
    i = int(np.argmax(np.abs(form)))
    if not rows.size:  # a smooth field: its largest value is at a point
        return float(form[i]), uv[i]
    start = uv[rows]
    centre = start.copy()
    value, scale, fits = smooth(uv, values, centre, sigma, tree, PEAK_GAMMA, PEAK, keep=True)
    inside = _surrounded(uv, start, tree)
    for _ in range(2):  # to the fitted peak, at most one point spacing from the point, and fitted again there
        moved = centre + _steps(fits, scale) - start
        moved *= np.minimum(1.0, spacing / np.maximum(np.linalg.norm(moved, axis=1), 1e-12))[:, None]
        centre = start + np.where(inside[:, None], moved, 0.0)
        refit, scale, fits = smooth(uv, values, centre, sigma, tree, PEAK_GAMMA, PEAK, keep=True)
        value = np.where(np.abs(refit) > np.abs(value), refit, value)
    if not value.size or np.abs(value).max() <= abs(form[i]):
        return float(form[i]), uv[i]
    j = int(np.argmax(np.abs(value)))
    return float(value[j]), centre[j]


def form_field(uv: np.ndarray, values: np.ndarray) -> FormField:
    """The form deviation of points (``uv`` (m, 2) mm, deviations (m,) mm) from themselves (see the module docstring)."""
    tree = cKDTree(uv)
    sigma = noise_mm(uv, values, tree)
    gamma = float(np.clip(np.sqrt(2.0 * np.log(max(uv.shape[0], 2))), *GAMMA_RANGE))
    form, scale, radius = smooth(uv, values, uv, sigma, tree, gamma)
    spacing = float(radius[0] * np.sqrt(np.pi / SCALES[0]))  # the square root of the area per point
    peak, where = _refine_peaks(uv, values, form, scale, sigma, tree, spacing)
    radius = np.asarray(radius, dtype=float)
    return FormField(form, scale, peak, np.asarray(where, dtype=float), sigma, spacing, radius)


MAX_POINTS = 40000
"""Above this many points the form field is computed on cell means of about this many cells (a dense scan's
neighbouring points averaged first; each point takes its cell's form value): the time stays bounded."""


def decimate(uv: np.ndarray, values: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(cell centroids (c, 2), cell mean values (c,), cell of each point (m,)) on a square grid of about ``count``
    occupied cells."""
    low = uv.min(axis=0)
    area = max(float(np.prod(np.ptp(uv, axis=0))), 1e-9)
    size = np.sqrt(area / count)
    for _ in range(8):  # the grid's occupied cells: near ``count`` (a scan need not fill its bounding box)
        keys = np.floor((uv - low) / size).astype(np.int64)
        _, cell = np.unique(keys[:, 0] * (keys[:, 1].max() + 1) + keys[:, 1], return_inverse=True)
        cells = int(cell.max()) + 1
        if cells <= 1.2 * count:
            break
        size *= np.sqrt(cells / count)
    weight = np.bincount(cell, minlength=cells).astype(float)
    centre = np.column_stack([np.bincount(cell, uv[:, k], cells) for k in range(2)]) / weight[:, None]
    return centre, np.bincount(cell, values, cells) / weight, cell


def form_of(uv: np.ndarray, deviation: np.ndarray, inlier: np.ndarray, measured_ok: np.ndarray,
            in_margin: np.ndarray) -> tuple[np.ndarray, FormField]:
    """The form deviation (n,) of the inliers and of the trim margin's usable points (NaN elsewhere), and the
    net plate's :class:`FormField`.

    The inliers' values come from the inliers alone (the net plate: the form statistics); the
    margin points' from all usable points, net and margin (for maps only). Above
    :data:`MAX_POINTS` inliers the field is that of cell means (:func:`decimate`).

    Parameters
    ----------
    uv : (n, 2) float, mm
        Foot points in the design plane.
    deviation : (n,) float, mm
    inlier, measured_ok, in_margin : (n,) bool
        The statistics' points; every point that is neither outside nor set aside; the
        points in the trim margin.
    """
    form = np.full(deviation.shape[0], np.nan)
    if inlier.sum() > MAX_POINTS:
        centre, mean, cell = decimate(uv[inlier], deviation[inlier], MAX_POINTS)
        net = form_field(centre, mean)
        form[inlier] = net.values[cell]
    else:
        net = form_field(uv[inlier], deviation[inlier])
        form[inlier] = net.values
    margin_ok = measured_ok & in_margin
    if margin_ok.any():  # for maps only: the net plate's form values above do not see the margin
        data = np.flatnonzero(measured_ok)
        if data.size > MAX_POINTS:
            data = np.sort(np.random.default_rng(0).choice(data, MAX_POINTS, replace=False))
        tree = cKDTree(uv[data])
        form[margin_ok] = smooth(uv[data], deviation[data], uv[margin_ok], max(net.noise_mm, 1e-6), tree)[0]
    return form, net
