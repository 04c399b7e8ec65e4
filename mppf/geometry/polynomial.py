"""The polynomial plate surface of the paper, eq. (1.1): z = sum a_ij s^i t^j for i, j <= k.

On centred and scaled coordinates s, t in [-1, 1], solved by least squares (QR with
column pivoting, never the normal equations of eq. 1.2); ``degree="auto"`` picks k by a
seeded held-out residual. The mathematics is in ``docs/math-surfaces.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.linalg import lstsq

from mppf.core.errors import GeometryError, InputError
from mppf.geometry.surface_math import Bounds, bounds_of, check_uvz, powers, residual_stats, unit_normals, uv_arrays

DEGREES = (2, 3, 4)
HOLDOUT_FRACTION = 0.2
"""Share of the points held out (deterministic, seeded) when ``degree="auto"``."""
AUTO_TOLERANCE = 0.05
"""``degree="auto"`` keeps the lowest degree whose held-out RMS is within 5 % of the best."""


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
        As in :class:`mppf.geometry.surface.Surface`.
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
        u_arr, v_arr = uv_arrays(u, v)
        s = (u_arr.ravel() - self.center_mm[0]) / self.scale_mm[0]
        t = (v_arr.ravel() - self.center_mm[1]) / self.scale_mm[1]
        return u_arr.shape, s, t

    def evaluate(self, u, v) -> np.ndarray:
        """Heights z (mm) at (u, v) (mm); same shape as the broadcast inputs."""
        shape, s, t = self._scaled(u, v)
        (ps,) = powers(s, self.degree, order=0)
        (pt,) = powers(t, self.degree, order=0)
        return np.einsum("in,in->n", ps, self.coefficients @ pt).reshape(shape)

    def derivatives(self, u, v) -> tuple[np.ndarray, ...]:
        """(z, zu, zv, zuu, zuv, zvv) at (u, v), each shaped like the inputs (mm, 1, 1/mm)."""
        shape, s, t = self._scaled(u, v)
        su, sv = self.scale_mm
        ps, dps, ddps = powers(s, self.degree)
        pt, dpt, ddpt = powers(t, self.degree)
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



def _solve_polynomial(u, v, z, k: int) -> PolynomialSurface:
    """Least-squares fit of degree (k, k) on centred, scaled coordinates."""
    (umin, umax), (vmin, vmax) = bounds_of(u, v)
    center = np.array([(umin + umax) / 2, (vmin + vmax) / 2])
    scale = np.array([(umax - umin) / 2, (vmax - vmin) / 2])
    if np.any(scale <= 1e-9 * max(1.0, float(np.abs(center).max()))):
        raise GeometryError(
            f"the points span no area in (u, v) (half ranges {scale.tolist()} mm)",
            hint="a surface needs points spread over the plate",
        )
    (ps,) = powers((u - center[0]) / scale[0], k, order=0)
    (pt,) = powers((v - center[1]) / scale[1], k, order=0)
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
    rms, max_abs = residual_stats(z - surface.evaluate(u, v))
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
    u, v, z = check_uvz(u, v, z)
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
