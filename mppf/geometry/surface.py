"""Plate surfaces z = D(u, v) in the plate's local frame: polynomial and B-spline.

Both kinds implement the :class:`Surface` protocol: vectorized values, first and
second derivatives and unit normals, the fitted bounds and the fit residual. Both
evaluate smoothly a little outside their bounds (the planner extends a plate over its
trim allowance). The mathematics is in ``docs/math-surfaces.md``.

- :class:`PolynomialSurface`: paper eq. (1.1), z = sum a_ij s^i t^j for i, j <= k,
  on centred and scaled coordinates s, t in [-1, 1], solved by least squares
  (QR with column pivoting, never the normal equations of eq. 1.2).
- :class:`SplineSurface`: a bicubic least-squares (fixed knots) or smoothing B-spline
  (scipy FITPACK), extended beyond its bounds by its first-order Taylor expansion.

:func:`fit_plate` is the one-call entry: frame, height-field check, fit, residual.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace
from typing import Protocol, runtime_checkable

import numpy as np
from scipy.interpolate import LSQBivariateSpline, SmoothBivariateSpline
from scipy.linalg import lstsq

from mppf.core.errors import GeometryError, InputError
from mppf.geometry.frame import LocalFrame, check_height_field, fit_frame
from mppf.geometry.io import check_plate
from mppf.core.transform import as_points

DEGREES = (2, 3, 4)
KINDS = ("poly", "spline")
HOLDOUT_FRACTION = 0.2
"""Share of the points held out (deterministic, seeded) when ``degree="auto"``."""
AUTO_TOLERANCE = 0.05
"""``degree="auto"`` keeps the lowest degree whose held-out RMS is within 5 % of the best."""
SPLINE_MIN_POINTS_PER_CELL = 16
"""Default knot spacing of the least-squares spline: about this many points per knot cell."""
SPLINE_MIN_POINTS_IN_CELL = 4
"""Fewest points any knot cell must hold; otherwise the knot grid is made coarser."""
SPLINE_MAX_INTERVALS = 12

Bounds = tuple[tuple[float, float], tuple[float, float]]


@runtime_checkable
class Surface(Protocol):
    """A height field z = D(u, v) in a plate's local frame (all lengths mm).

    Attributes
    ----------
    bounds : ((umin, umax), (vmin, vmax))
        The (u, v) range of the fitted points.
    rms_mm, max_abs_mm : float
        RMS and largest absolute vertical residual of the fit.
    kind : str
        ``"poly"`` or ``"spline"``.
    degree : int
        Polynomial degree k of (k, k), or 3 for the bicubic spline.
    """

    bounds: Bounds
    rms_mm: float
    max_abs_mm: float
    kind: str
    degree: int

    def evaluate(self, u, v) -> np.ndarray:
        """Heights z (mm) at (u, v), arrays of one shape; same shape out."""

    def derivatives(self, u, v) -> tuple[np.ndarray, ...]:
        """(z, zu, zv, zuu, zuv, zvv) at (u, v)."""

    def normals(self, u, v) -> np.ndarray:
        """Unit normals (..., 3) toward +w: (-zu, -zv, 1) / norm."""


def _uv_arrays(u, v) -> tuple[np.ndarray, np.ndarray]:
    u_arr, v_arr = np.broadcast_arrays(np.asarray(u, dtype=float), np.asarray(v, dtype=float))
    return u_arr, v_arr


def unit_normals(zu, zv) -> np.ndarray:
    """Unit normals (..., 3) of z = D(u, v) from its slopes, pointing to +w."""
    zu = np.asarray(zu, dtype=float)
    zv = np.asarray(zv, dtype=float)
    n = np.stack([-zu, -zv, np.ones_like(zu)], axis=-1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def _residual_stats(residual: np.ndarray) -> tuple[float, float]:
    return float(np.sqrt(np.mean(residual**2))), float(np.max(np.abs(residual)))


# --------------------------------------------------------------------- polynomial


def _powers(x: np.ndarray, k: int, order: int = 2) -> list[np.ndarray]:
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


@dataclass(frozen=True, eq=False)
class PolynomialSurface:
    """z = sum_{i,j<=k} a_ij s^i t^j with s = (u - cu)/su, t = (v - cv)/sv (paper eq. 1.1).

    Attributes
    ----------
    coefficients : (k+1, k+1) float
        a_ij in mm, i the power of s, j the power of t.
    center_mm, scale_mm : (2,) float
        Centre and half range of (u, v) used for scaling.
    bounds, rms_mm, max_abs_mm, degree, kind
        As in :class:`Surface`.
    heldout_rms_mm : tuple of (degree, rms_mm)
        The held-out RMS of each degree tried when the degree was chosen automatically.
    """

    coefficients: np.ndarray
    center_mm: np.ndarray
    scale_mm: np.ndarray
    bounds: Bounds
    rms_mm: float = 0.0
    max_abs_mm: float = 0.0
    heldout_rms_mm: tuple = ()
    kind: str = field(default="poly", init=False)

    @property
    def degree(self) -> int:
        """k of the (k, k) polynomial."""
        return self.coefficients.shape[0] - 1

    def _scaled(self, u, v):
        u_arr, v_arr = _uv_arrays(u, v)
        s = (u_arr.ravel() - self.center_mm[0]) / self.scale_mm[0]
        t = (v_arr.ravel() - self.center_mm[1]) / self.scale_mm[1]
        return u_arr.shape, s, t

    def evaluate(self, u, v) -> np.ndarray:
        """Heights z (mm) at (u, v) (mm); same shape as the broadcast inputs."""
        shape, s, t = self._scaled(u, v)
        (ps,) = _powers(s, self.degree, order=0)
        (pt,) = _powers(t, self.degree, order=0)
        return np.einsum("in,in->n", ps, self.coefficients @ pt).reshape(shape)

    def derivatives(self, u, v) -> tuple[np.ndarray, ...]:
        """(z, zu, zv, zuu, zuv, zvv) at (u, v), each shaped like the inputs (mm, 1, 1/mm)."""
        shape, s, t = self._scaled(u, v)
        su, sv = self.scale_mm
        ps, dps, ddps = _powers(s, self.degree)
        pt, dpt, ddpt = _powers(t, self.degree)
        # b_i(t) = sum_j a_ij t^j and its t-derivatives, then dot with the s powers
        a = self.coefficients
        b, db, ddb = a @ pt, a @ dpt, a @ ddpt
        row = "in,in->n"
        out = (
            np.einsum(row, ps, b),
            np.einsum(row, dps, b) / su,
            np.einsum(row, ps, db) / sv,
            np.einsum(row, ddps, b) / (su * su),
            np.einsum(row, dps, db) / (su * sv),
            np.einsum(row, ps, ddb) / (sv * sv),
        )
        return tuple(x.reshape(shape) for x in out)

    def normals(self, u, v) -> np.ndarray:
        """Unit normals (..., 3) toward +w."""
        _, zu, zv, *_ = self.derivatives(u, v)
        return unit_normals(zu, zv)


def _check_uvz(u, v, z) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    arrays = [np.asarray(x, dtype=float) for x in (u, v, z)]
    if any(a.ndim != 1 for a in arrays) or len({a.shape for a in arrays}) != 1:
        raise InputError(
            f"u, v, z must be 1-D arrays of one length, got shapes {[a.shape for a in arrays]}",
            hint="pass the columns of the local points separately",
        )
    if not all(np.all(np.isfinite(a)) for a in arrays):
        raise InputError("u, v, z contain NaN or infinite values")
    return arrays[0], arrays[1], arrays[2]


def _bounds(u: np.ndarray, v: np.ndarray) -> Bounds:
    return (float(u.min()), float(u.max())), (float(v.min()), float(v.max()))


def _solve_polynomial(u, v, z, k: int) -> PolynomialSurface:
    """Least-squares fit of degree (k, k) on centred, scaled coordinates."""
    (umin, umax), (vmin, vmax) = _bounds(u, v)
    center = np.array([(umin + umax) / 2, (vmin + vmax) / 2])
    scale = np.array([(umax - umin) / 2, (vmax - vmin) / 2])
    if np.any(scale <= 1e-9 * max(1.0, float(np.abs(center).max()))):
        raise GeometryError(
            f"the points span no area in (u, v) (half ranges {scale.tolist()} mm)",
            hint="a surface needs points spread over the plate",
        )
    (ps,) = _powers((u - center[0]) / scale[0], k, order=0)
    (pt,) = _powers((v - center[1]) / scale[1], k, order=0)
    design = (ps.T[:, :, None] * pt.T[:, None, :]).reshape(len(u), -1)
    # QR with column pivoting (LAPACK gelsy): rank-revealing, never the normal equations
    coef, _, rank, _ = lstsq(design, z, lapack_driver="gelsy", check_finite=False)
    if rank < design.shape[1]:
        raise GeometryError(
            f"the {len(u)} points do not determine a degree ({k}, {k}) surface "
            f"(rank {rank} of {design.shape[1]}): they lie on too few distinct lines",
            hint="use a lower degree or points spread over the whole plate",
        )
    surface = PolynomialSurface(coefficients=coef.reshape(k + 1, k + 1), center_mm=center, scale_mm=scale,
                                bounds=((umin, umax), (vmin, vmax)))
    rms, max_abs = _residual_stats(z - surface.evaluate(u, v))
    return replace(surface, rms_mm=rms, max_abs_mm=max_abs)


def _choose_degree(u, v, z) -> tuple[int, tuple]:
    """Pick k by the RMS on a held-out, seeded random 20 % of the points."""
    order = np.random.default_rng(0).permutation(len(u))
    n_test = int(round(HOLDOUT_FRACTION * len(u)))
    test, train = order[:n_test], order[n_test:]
    scores = []
    for k in DEGREES:
        if len(train) < (k + 1) ** 2 or n_test == 0:
            continue
        try:
            surf = _solve_polynomial(u[train], v[train], z[train], k)
        except GeometryError:
            continue
        resid = z[test] - surf.evaluate(u[test], v[test])
        scores.append((k, float(np.sqrt(np.mean(resid**2)))))
    if not scores:
        raise GeometryError(
            f"{len(u)} points are too few to choose a degree automatically",
            hint=f"give at least {int((DEGREES[0] + 1) ** 2 / (1 - HOLDOUT_FRACTION)) + 1} points or a fixed degree",
        )
    best = min(rms for _, rms in scores)
    chosen = next(k for k, rms in scores if rms <= best * (1 + AUTO_TOLERANCE) + 1e-6)
    return chosen, tuple(scores)


def fit_polynomial(u, v, z, degree: int | str = 3) -> PolynomialSurface:
    """Fit z = D(u, v) of degree (k, k) by least squares (paper eq. 1.1-1.3, corrected).

    Parameters
    ----------
    u, v, z : (n,) float, mm
        Local coordinates of the points.
    degree : {2, 3, 4, "auto"}
        k; ``"auto"`` picks the lowest k whose held-out RMS (seeded 20 % split) is
        within 5 % of the best, then refits on all points.

    Returns
    -------
    PolynomialSurface

    Raises
    ------
    InputError
        Unknown degree or bad arrays.
    GeometryError
        Too few or degenerate points for the degree.
    """
    u, v, z = _check_uvz(u, v, z)
    scores: tuple = ()
    if degree == "auto":
        degree, scores = _choose_degree(u, v, z)
    if degree not in DEGREES:
        raise InputError(f"polynomial degree must be one of {DEGREES} or 'auto', got {degree!r}")
    if len(u) < (degree + 1) ** 2:
        raise GeometryError(
            f"{len(u)} points, a degree ({degree}, {degree}) fit needs at least {(degree + 1) ** 2}",
            hint="give more points or a lower degree",
        )
    return replace(_solve_polynomial(u, v, z, degree), heldout_rms_mm=scores)


# --------------------------------------------------------------------- spline


@dataclass(frozen=True, eq=False)
class SplineSurface:
    """A bicubic B-spline z = S(u, v) with a C1 extension beyond its bounds.

    Inside ``bounds`` it is the scipy spline. For fast vectorized evaluation the
    spline is converted once into its bicubic pieces (one 4 x 4 polynomial per knot
    cell, exact to round-off). Outside, with c the nearest point of the bounds and
    (du, dv) = (u, v) - c, it is S(c) + S_u(c) du + S_v(c) dv (the tangent plane at
    the edge), so the heights and slopes are continuous.

    Attributes
    ----------
    spline : scipy.interpolate.BivariateSpline
    bounds, rms_mm, max_abs_mm, degree, kind
        As in :class:`Surface`.
    smoothing : float or None
        Target RMS (mm) of a smoothing spline, None for fixed-knot least squares.
    """

    spline: object
    bounds: Bounds
    rms_mm: float = 0.0
    max_abs_mm: float = 0.0
    smoothing: float | None = None
    degree: int = field(default=3, init=False)
    kind: str = field(default="spline", init=False)
    _breaks: tuple = field(default=(), init=False, repr=False)
    _patches: np.ndarray | None = field(default=None, init=False, repr=False)

    def __post_init__(self):
        tx, ty = self.spline.get_knots()
        bu, bv = np.unique(tx), np.unique(ty)
        # sample each cell at 4 x 4 points and solve for its bicubic coefficients
        nodes = np.linspace(0.0, 1.0, 4)
        gu = (bu[:-1, None] + np.diff(bu)[:, None] * nodes).ravel()
        gv = (bv[:-1, None] + np.diff(bv)[:, None] * nodes).ravel()
        mu, mv = np.meshgrid(gu, gv, indexing="ij")
        values = self.spline.ev(mu.ravel(), mv.ravel()).reshape(len(bu) - 1, 4, len(bv) - 1, 4)
        inv = np.linalg.inv(np.vander(nodes, 4, increasing=True))
        patches = np.einsum("pk,ikjl,ql->ijpq", inv, values, inv)  # (cells u, cells v, 4, 4)
        object.__setattr__(self, "_breaks", (bu, bv))
        object.__setattr__(self, "_patches", patches)

    @property
    def knots(self) -> tuple[np.ndarray, np.ndarray]:
        """Knot vectors (u, v) in mm, end knots included."""
        return self.spline.get_knots()

    def _split(self, u, v):
        u_arr, v_arr = _uv_arrays(u, v)
        (umin, umax), (vmin, vmax) = self.bounds
        uu, vv = u_arr.ravel(), v_arr.ravel()
        cu, cv = np.clip(uu, umin, umax), np.clip(vv, vmin, vmax)
        return u_arr.shape, cu, cv, uu - cu, vv - cv

    def _pieces(self, cu, cv, orders) -> list[np.ndarray]:
        """Partial derivatives d^(a+b) S / du^a dv^b at points inside the bounds, per (a, b)."""
        bu, bv = self._breaks
        i = np.clip(np.searchsorted(bu, cu, side="right") - 1, 0, len(bu) - 2)
        j = np.clip(np.searchsorted(bv, cv, side="right") - 1, 0, len(bv) - 2)
        hu, hv = bu[i + 1] - bu[i], bv[j + 1] - bv[j]
        top = max(max(a for a, _ in orders), max(b for _, b in orders))
        pa = _powers((cu - bu[i]) / hu, 3, order=top)
        pb = _powers((cv - bv[j]) / hv, 3, order=top)
        # coefficients c_pq of each point's cell as (4, 4, n): contiguous rows, fast sums
        coef = self._patches.reshape(-1, 16).T[:, i * (len(bv) - 1) + j].reshape(4, 4, -1)
        cache: dict[int, np.ndarray] = {}
        out = []
        for a, b in orders:
            if b not in cache:  # sum over q of c_pq d^b(beta^q), (4, n)
                cache[b] = np.einsum("pqn,qn->pn", coef, pb[b])
            out.append(np.einsum("pn,pn->n", cache[b], pa[a]) / (hu**a * hv**b))
        return out

    def evaluate(self, u, v) -> np.ndarray:
        """Heights z (mm) at (u, v) (mm); same shape as the broadcast inputs."""
        shape, cu, cv, du, dv = self._split(u, v)
        s, su, sv = self._pieces(cu, cv, [(0, 0), (1, 0), (0, 1)])
        return (s + su * du + sv * dv).reshape(shape)

    def derivatives(self, u, v) -> tuple[np.ndarray, ...]:
        """(z, zu, zv, zuu, zuv, zvv) at (u, v), each shaped like the inputs."""
        shape, cu, cv, du, dv = self._split(u, v)
        inside_u = (du == 0).astype(float)
        inside_v = (dv == 0).astype(float)
        s, su, sv, suu, suv, svv, suuv, suvv = self._pieces(
            cu, cv, [(0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2), (2, 1), (1, 2)]
        )
        out = (
            s + su * du + sv * dv,
            su + inside_u * suv * dv,
            sv + inside_v * suv * du,
            inside_u * (suu + suuv * dv),
            np.where((inside_u + inside_v) > 0, suv, 0.0),
            inside_v * (svv + suvv * du),
        )
        return tuple(x.reshape(shape) for x in out)

    def normals(self, u, v) -> np.ndarray:
        """Unit normals (..., 3) toward +w."""
        _, zu, zv, *_ = self.derivatives(u, v)
        return unit_normals(zu, zv)


def _uniform_knots(lo: float, hi: float, intervals: int) -> np.ndarray:
    return np.linspace(lo, hi, intervals + 1)[1:-1]


def fit_spline(u, v, z, smoothing: float | None = None) -> SplineSurface:
    """Fit a bicubic B-spline z = S(u, v).

    Parameters
    ----------
    u, v, z : (n,) float, mm
    smoothing : float, optional
        Target RMS residual in mm: a FITPACK smoothing spline with s = n * smoothing^2
        places its own knots. None: least squares on uniform knots, about 16 points per
        knot cell (at most 12 intervals per axis); the knot grid is halved until every
        cell holds at least 4 points (holes in a scan) and FITPACK reports no rank
        deficiency.

    Returns
    -------
    SplineSurface

    Raises
    ------
    GeometryError
        Too few points (16) or FITPACK cannot reach the requested smoothing.
    """
    u, v, z = _check_uvz(u, v, z)
    if len(u) < 16:
        raise GeometryError(f"{len(u)} points, a bicubic spline needs at least 16", hint="give more points")
    (umin, umax), (vmin, vmax) = bounds = _bounds(u, v)
    if umax - umin <= 0 or vmax - vmin <= 0:
        raise GeometryError("the points span no area in (u, v)", hint="a surface needs points spread over the plate")
    if smoothing is not None:
        if not 0 < smoothing < np.inf:
            raise InputError(f"spline smoothing must be a positive, finite RMS in mm, got {smoothing!r}",
                             hint="give the residual RMS you accept, e.g. 0.5, or leave it out")
        spline = _fitpack(lambda: SmoothBivariateSpline(u, v, z, s=len(u) * smoothing**2, kx=3, ky=3),
                          f"smoothing {smoothing} mm")
    else:
        aspect = (umax - umin) / (vmax - vmin)
        cells = len(u) / SPLINE_MIN_POINTS_PER_CELL
        nu = int(np.clip(np.sqrt(cells * aspect), 1, SPLINE_MAX_INTERVALS))
        nv = int(np.clip(np.sqrt(cells / aspect), 1, SPLINE_MAX_INTERVALS))
        while True:
            # every knot cell needs data, or the spline is arbitrary there (holes in a scan)
            counts, _, _ = np.histogram2d(u, v, bins=[nu, nv], range=[[umin, umax], [vmin, vmax]])
            tx, ty = _uniform_knots(umin, umax, nu), _uniform_knots(vmin, vmax, nv)
            try:
                if counts.min() < SPLINE_MIN_POINTS_IN_CELL:
                    raise GeometryError(f"a {nu}x{nv} knot grid has cells with {int(counts.min())} points")
                spline = _fitpack(lambda: LSQBivariateSpline(u, v, z, tx, ty, kx=3, ky=3), f"{nu}x{nv} knot intervals")
                break
            except GeometryError:
                if nu == 1 and nv == 1:
                    raise
                nu, nv = max(1, nu // 2), max(1, nv // 2)
    rms, max_abs = _residual_stats(z - spline.ev(u, v))
    return SplineSurface(spline=spline, bounds=bounds, rms_mm=rms, max_abs_mm=max_abs, smoothing=smoothing)


def _fitpack(build, what: str):
    """Run a FITPACK fit, turning its warnings (rank deficiency, storage) into GeometryError."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            spline = build()
        except ValueError as exc:
            raise GeometryError(f"B-spline fit with {what} failed: {exc}",
                                hint="use more points or the polynomial surface") from None
    if caught:
        raise GeometryError(f"B-spline fit with {what} is unreliable: {str(caught[0].message).strip()[:200]}",
                            hint="use a larger smoothing, more points, or the polynomial surface")
    return spline


# --------------------------------------------------------------------- curvature


@dataclass(frozen=True, eq=False)
class Curvatures:
    """Curvatures of z = D(u, v) from its fundamental forms (signs: + bends toward +w).

    Attributes
    ----------
    k1, k2 : (n,) float, 1/mm
        Principal curvatures, k1 >= k2 (positive: concave seen from +w).
    mean, gaussian : (n,) float
        Mean curvature (k1 + k2) / 2 (1/mm), Gaussian curvature k1 k2 (1/mm^2).
    dir1, dir2 : (n, 2) float
        Principal directions as unit (du, dv) in the parameter plane (the 3-D
        direction is du (1, 0, zu) + dv (0, 1, zv)).
    """

    k1: np.ndarray
    k2: np.ndarray
    mean: np.ndarray
    gaussian: np.ndarray
    dir1: np.ndarray
    dir2: np.ndarray


def _principal_direction(e, f, g, l_, m, n_, k) -> np.ndarray:
    """Unit (du, dv) solving (II - k I) d = 0, picking the better-conditioned row."""
    a, b = m - k * f, -(l_ - k * e)  # from row 1: (L - kE) du + (M - kF) dv = 0
    c, d = n_ - k * g, -(m - k * f)  # from row 2: (M - kF) du + (N - kG) dv = 0
    use_first = np.hypot(a, b) >= np.hypot(c, d)
    du = np.where(use_first, a, c)
    dv = np.where(use_first, b, d)
    norm = np.hypot(du, dv)
    umbilic = norm <= 1e-15 * (np.abs(l_) + np.abs(m) + np.abs(n_) + 1e-300)
    du = np.where(umbilic, 1.0, du)
    dv = np.where(umbilic, 0.0, dv)
    return np.column_stack([du, dv]) / np.hypot(du, dv)[:, None]


def curvatures(surface: Surface, u, v) -> Curvatures:
    """Principal, mean and Gaussian curvature at (u, v).

    First fundamental form E = 1 + zu^2, F = zu zv, G = 1 + zv^2; second form with
    the unit normal toward +w: L = zuu / W, M = zuv / W, N = zvv / W, W = sqrt(1 +
    zu^2 + zv^2). K = (LN - M^2) / (EG - F^2), H = (EN - 2FM + GL) / (2 (EG - F^2)),
    k1,2 = H +- sqrt(H^2 - K).

    Parameters
    ----------
    surface : Surface
    u, v : (n,) float, mm

    Returns
    -------
    Curvatures
    """
    u_arr, v_arr = _uv_arrays(u, v)
    _, zu, zv, zuu, zuv, zvv = (x.ravel() for x in surface.derivatives(u_arr.ravel(), v_arr.ravel()))
    w = np.sqrt(1.0 + zu * zu + zv * zv)
    e, f, g = 1.0 + zu * zu, zu * zv, 1.0 + zv * zv
    l_, m, n_ = zuu / w, zuv / w, zvv / w
    det = e * g - f * f
    gaussian = (l_ * n_ - m * m) / det
    mean = (e * n_ - 2.0 * f * m + g * l_) / (2.0 * det)
    root = np.sqrt(np.maximum(mean * mean - gaussian, 0.0))
    k1, k2 = mean + root, mean - root
    return Curvatures(
        k1=k1, k2=k2, mean=mean, gaussian=gaussian,
        dir1=_principal_direction(e, f, g, l_, m, n_, k1),
        dir2=_principal_direction(e, f, g, l_, m, n_, k2),
    )


def principal_curvatures(surface: Surface, u, v) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(k1, k2, dir1): principal curvatures (1/mm, k1 >= k2) and the (n, 2) unit (du, dv) of k1.

    See :func:`curvatures` for mean and Gaussian curvature and the second direction.
    """
    c = curvatures(surface, u, v)
    return c.k1, c.k2, c.dir1


# --------------------------------------------------------------------- plates


@dataclass(frozen=True, eq=False)
class FittedPlate:
    """A plate's local frame and its fitted surface.

    Attributes
    ----------
    frame : LocalFrame
        Best-fit-plane frame; the surface lives in its (u, v, w) coordinates.
    surface : Surface
    residual_mm : (n,) float
        Signed vertical residual w - D(u, v) of each input point.
    rms_mm, max_abs_mm : float
    degree : int
    kind : str
    """

    frame: LocalFrame
    surface: Surface
    residual_mm: np.ndarray
    rms_mm: float
    max_abs_mm: float
    degree: int
    kind: str

    @property
    def n_points(self) -> int:
        """Number of points fitted."""
        return int(self.residual_mm.shape[0])


def fit_plate(points, degree: int | str = 3, kind: str = "poly", smoothing: float | None = None,
              *, faces=None, source: str = "points") -> FittedPlate:
    """Frame, height-field check and surface fit of a plate in one call.

    Parameters
    ----------
    points : (n, 3) float, mm, world (e.g. hull) coordinates
    degree : {2, 3, 4, "auto"}
        Polynomial degree (ignored for splines, which are bicubic).
    kind : {"poly", "spline"}
    smoothing : float, optional
        Spline target RMS in mm (see :func:`fit_spline`).
    faces : (m, 3) int, optional
        Mesh triangles, for an exact fold-over check.
    source : str
        Name for messages (the file name).

    Returns
    -------
    FittedPlate

    Raises
    ------
    InputError
        Unknown kind or degree, or smoothing for a polynomial.
    GeometryError
        Too few, coincident or collinear points; a plate that folds over in its frame.
    """
    if kind not in KINDS:
        raise InputError(f"surface kind must be one of {KINDS}, got {kind!r}")
    if kind == "poly" and smoothing is not None:
        raise InputError(f"smoothing ({smoothing} mm) applies to the spline surface only",
                         hint="use kind 'spline' or leave smoothing out")
    if kind == "poly" and degree not in DEGREES and degree != "auto":
        raise InputError(f"polynomial degree must be one of {DEGREES} or 'auto', got {degree!r}")
    min_points = 16 if kind == "spline" or degree == "auto" else (degree + 1) ** 2
    pts = check_plate(as_points(points, name=source), min_points, source)
    frame = fit_frame(pts)
    check_height_field(frame, pts, faces, source=source)
    u, v, w = frame.to_local(pts).T
    if kind == "poly":
        surface = fit_polynomial(u, v, w, degree=degree)
    else:
        surface = fit_spline(u, v, w, smoothing=smoothing)
    residual = w - surface.evaluate(u, v)
    rms, max_abs = _residual_stats(residual)
    return FittedPlate(frame=frame, surface=surface, residual_mm=residual, rms_mm=rms, max_abs_mm=max_abs,
                       degree=surface.degree, kind=surface.kind)
