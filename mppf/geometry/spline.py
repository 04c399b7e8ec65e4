"""The B-spline plate surface: a bicubic least-squares (fixed knots) or smoothing B-spline.

Fitted by scipy's FITPACK, evaluated through its bicubic pieces, and extended beyond its
bounds by its first-order Taylor expansion (the tangent plane at the edge). The
mathematics is in ``docs/math-surfaces.md``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import LSQBivariateSpline, SmoothBivariateSpline

from mppf.core.errors import GeometryError, InputError
from mppf.geometry.surface_math import (
    Bounds,
    bounds_of,
    check_uvz,
    residual_stats,
    unit_normals,
    uv_arrays,
)

SPLINE_MIN_POINTS_PER_CELL = 16
"""Default knot spacing of the least-squares spline: about this many points per knot cell."""
SPLINE_MIN_POINTS_IN_CELL = 4
"""Fewest points any knot cell must hold; otherwise the knot grid is made coarser."""
SPLINE_MAX_INTERVALS = 12


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
        As in :class:`mppf.geometry.surface.Surface`.
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
    _coefficients: np.ndarray | None = field(default=None, init=False, repr=False)
    _steps: tuple = field(default=(None, None), init=False, repr=False)

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
        object.__setattr__(self, "_steps", (_even_step(bu), _even_step(bv)))
        object.__setattr__(self, "_patches", patches)
        object.__setattr__(self, "_coefficients", np.ascontiguousarray(patches.reshape(-1, 16).T))  # (16, cells)

    @property
    def knots(self) -> tuple[np.ndarray, np.ndarray]:
        """Knot vectors (u, v) in mm, end knots included."""
        return self.spline.get_knots()

    def _split(self, u, v):
        u_arr, v_arr = uv_arrays(u, v)
        (umin, umax), (vmin, vmax) = self.bounds
        uu, vv = u_arr.ravel(), v_arr.ravel()
        cu, cv = np.clip(uu, umin, umax), np.clip(vv, vmin, vmax)
        return u_arr.shape, cu, cv, uu - cu, vv - cv

    def _pieces(self, cu, cv, orders) -> list[np.ndarray]:
        """Partial derivatives d^(a+b) S / du^a dv^b at points inside the bounds, per (a, b).

        Each point's bicubic piece is summed by Horner's rule, first along v (one row per power of
        u, per order b), then along u: about 30 array operations for the heights and slopes.
        """
        bu, bv = self._breaks
        i, j = _cell(bu, cu, self._steps[0]), _cell(bv, cv, self._steps[1])
        hu, hv = bu[i + 1] - bu[i], bv[j + 1] - bv[j]
        x, y = (cu - bu[i]) / hu, (cv - bv[j]) / hv
        # coefficients c_pq of each point's cell: row 4 p + q of a (16, n) array, rows contiguous
        coef = np.take(self._coefficients, i * (len(bv) - 1) + j, axis=1)
        rows: dict[int, list[np.ndarray]] = {}
        out = []
        for a, b in orders:
            if b not in rows:  # sum over q of c_pq d^b(y^q), one array per p
                rows[b] = [_horner_derivative(coef[4 * p:4 * p + 4], b, y) for p in range(4)]
            out.append(_horner_derivative(rows[b], a, x) / (hu**a * hv**b))
        return out

    def evaluate(self, u, v) -> np.ndarray:
        """Heights z (mm) at (u, v) (mm); same shape as the broadcast inputs."""
        shape, cu, cv, du, dv = self._split(u, v)
        s = self._pieces(cu, cv, [(0, 0)])[0]
        outside = np.flatnonzero((du != 0.0) | (dv != 0.0))  # only there the tangent plane needs the slopes
        if outside.size:
            su, sv = self._pieces(cu[outside], cv[outside], [(1, 0), (0, 1)])
            s[outside] = s[outside] + su * du[outside] + sv * dv[outside]
        return s.reshape(shape)

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


def _even_step(breaks: np.ndarray) -> float | None:
    """The spacing of evenly spaced breaks (to 1e-9 relative), None when uneven."""
    step = (breaks[-1] - breaks[0]) / (len(breaks) - 1)
    return float(step) if np.allclose(np.diff(breaks), step, rtol=1e-9, atol=0.0) else None


def _cell(breaks: np.ndarray, c: np.ndarray, step: float | None = None) -> np.ndarray:
    """Index k of the knot cell [breaks[k], breaks[k + 1]) holding each c (the first or last cell beyond them).

    The same as ``searchsorted(breaks, c, side="right") - 1`` clipped to the cells; on evenly spaced
    breaks (the least-squares spline's; ``step`` their spacing from :func:`_even_step`) computed from
    the spacing and corrected by one cell where rounding put a point next to its cell, several times
    faster on large arrays.
    """
    cells = len(breaks) - 1
    if step is None:
        return np.clip(np.searchsorted(breaks, c, side="right") - 1, 0, cells - 1)
    k = np.clip(((c - breaks[0]) / step).astype(np.intp), 0, cells - 1)
    k -= breaks[k] > c
    k = np.maximum(k, 0)
    k += (k < cells - 1) & (breaks[np.minimum(k + 1, cells)] <= c)
    return k


_FALLING = ((1.0, 1.0, 1.0, 1.0), (0.0, 1.0, 2.0, 3.0), (0.0, 0.0, 2.0, 6.0))
"""k! / (k - order)!: the factor of c_k x^(k - order) in the order-th derivative of c_k x^k."""


def _horner_derivative(coefficients, order: int, x: np.ndarray) -> np.ndarray:
    """d^order/dx^order of the cubic sum_k c_k x^k at x, by Horner's rule.

    Parameters
    ----------
    coefficients : sequence of 4 (n,) float
        c_0 .. c_3 per point.
    order : int
        0, 1 or 2.
    x : (n,) float

    Returns
    -------
    (n,) float
    """
    factor = _FALLING[order]
    out = coefficients[3] * factor[3]
    for k in range(2, order - 1, -1):
        out *= x
        out += coefficients[k] * factor[k] if order else coefficients[k]
    return out


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
    u, v, z = check_uvz(u, v, z)
    if len(u) < 16:
        raise GeometryError(f"{len(u)} points, a bicubic spline needs at least 16", hint="give more points")
    (umin, umax), (vmin, vmax) = bounds = bounds_of(u, v)
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
                spline = _fitpack(lambda tx=tx, ty=ty: LSQBivariateSpline(u, v, z, tx, ty, kx=3, ky=3),
                                  f"{nu}x{nv} knot intervals")
                break
            except GeometryError:
                if nu == 1 and nv == 1:
                    raise
                nu, nv = max(1, nu // 2), max(1, nv // 2)
    rms, max_abs = residual_stats(z - spline.ev(u, v))
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
