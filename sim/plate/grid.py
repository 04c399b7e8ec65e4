"""The plate's finite-element grid: bicubic B-splines over the plate as cut.

The deflection of the mid-surface (press z) is a tensor-product cubic B-spline
``w(u, v) = sum_ij c_ij N_i(v) M_j(u)`` on a regular grid of cells of at most
``spacing_mm`` in the plate's own frame (u along the long side of the smallest rectangle
around the outline, v across; origin at its centre). Clamped knot vectors at the edges.
The basis is C2, so the Kirchhoff curvatures are exact in every cell (an isogeometric
Kirchhoff plate: no rotations as unknowns) and free edges need nothing (natural boundary
conditions of the energy). Cubic B-splines reproduce quadratics: a uniform curvature field
is represented exactly.

Integration: 2 x 2 Gauss points per cell; a Gauss point outside the outline has weight 0
(non-rectangular outlines are trimmed at quarter-cell resolution) and cells without an
inside point are dropped, as are the coefficients no kept cell uses.

Unknowns ("dofs") are the used coefficients numbered along v first, so every cell's
16 x 16 block lies within a band of about ``3 (nv + 1)``: matrices are assembled straight
into LAPACK's symmetric band storage and factorised by banded Cholesky
(:meth:`PlateGrid.band`, :func:`band_solver`). ``cylindrical=True`` makes the deflection
``w(u)`` only (``c_ij = c_0j``: one dof per column), the plane-strain kinematics of a wide
plate bent about v, used by the closed-form checks.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
from scipy.interpolate import BSpline, NdBSpline

from mppf.core.polygon import as_polygon, contains, convex_outline
from mppf.core.validate import check_positive

DEGREE = 3
GAUSS_1D = np.array([-1.0, 1.0]) / np.sqrt(3.0)


def plate_frame(outline_xy_mm) -> tuple[np.ndarray, float, np.ndarray]:
    """The plate's frame: centre, angle and size of the smallest rectangle around the outline.

    Parameters
    ----------
    outline_xy_mm : (k, 2) float
        Outline in press x, y, mm.

    Returns
    -------
    centre_xy_mm : (2,) float
        Centre of the rectangle (origin of u, v).
    angle_rad : float
        Direction of u (the rectangle's longer side) from press x, in (-pi/2, pi/2].
    size_mm : (2,) float
        Length along u and width along v.
    """
    hull = convex_outline(outline_xy_mm, "the plate outline")
    areas = []
    for a, b in zip(hull, np.roll(hull, -1, axis=0)):
        angle = float(np.arctan2(b[1] - a[1], b[0] - a[0]))
        areas.append((np.prod(np.ptp(hull @ rotation_2d(angle), axis=0)), angle))
    angle = min(areas)[1]
    size = np.ptp(hull @ rotation_2d(angle), axis=0)
    if size[1] > size[0] + 1e-9:
        angle += 0.5 * np.pi
    angle = float(np.arctan(np.tan(angle))) if abs(np.cos(angle)) > 1e-12 else 0.5 * np.pi
    uv = hull @ rotation_2d(angle)
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    return 0.5 * (lo + hi) @ rotation_2d(angle).T, angle, hi - lo


def rotation_2d(angle: float) -> np.ndarray:
    """Columns (2, 2): u and v axes in press x, y (so ``xy @ R`` gives u, v); ``angle`` in radians."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def basis(knots: np.ndarray, x, derivative: int = 0) -> np.ndarray:
    """Values (m, n) of the n cubic B-splines (or a derivative) at ``x`` (m,)."""
    n = len(knots) - DEGREE - 1
    return BSpline(knots, np.eye(n), DEGREE, extrapolate=True)(np.asarray(x, dtype=float), nu=derivative)


def band_solver(band: np.ndarray):
    """Solve function of a symmetric positive definite band matrix (lower form, (bw + 1, n)).

    Returns
    -------
    callable
        ``solve(rhs)`` for rhs (n,) or (n, k).

    Raises
    ------
    numpy.linalg.LinAlgError
        The matrix is not positive definite.
    """
    factor = scipy.linalg.cholesky_banded(band, lower=True, check_finite=False)
    return lambda rhs: scipy.linalg.cho_solve_banded((factor, True), rhs, check_finite=False)


class PlateGrid:
    """B-spline grid of a plate.

    Parameters
    ----------
    outline_xy_mm : (k, 2) float
        The plate as cut, press x, y, mm.
    spacing_mm : float
        Largest cell size.
    cylindrical : bool
        Deflections ``w(u)`` only (plane strain about v).

    Attributes
    ----------
    centre_xy_mm, angle_rad, size_mm
        The plate frame (:func:`plate_frame`).
    knots_u, knots_v : float arrays
        Clamped knot vectors in u, v (mm).
    n_u, n_v, n_coef : int
        Coefficients along u, along v and in all (row-major (v, u)).
    n_dof : int
        Unknowns.
    gauss_uv : (g, 2) float
        Gauss points in u, v (4 per kept cell, in cell order).
    gauss_weight_mm2 : (g,) float
        Area weights (0 outside the outline).
    cell_uv : (e, 2) int
        (cell along u, cell along v) of each kept cell.
    cell_dof : (e, 16) int
        The unknowns of each kept cell.
    gauss_dof : (g, 16) int
        The unknowns of each Gauss point's cell.
    coef_dof : (n_coef,) int
        The unknown of each coefficient (-1: unused).
    curvature : (g, 3, 16) float
        kappa = -(w_uu, w_vv, 2 w_uv) of each Gauss point from its cell's unknowns.
    value : (g, 16) float
        w at each Gauss point from its cell's unknowns.
    bandwidth : int
        Largest distance of two unknowns of one cell.
    """

    def __init__(self, outline_xy_mm, spacing_mm: float, *, cylindrical: bool = False):
        self.outline_xy_mm = as_polygon(outline_xy_mm, "the plate outline")
        self.spacing_mm = check_positive("grid spacing", spacing_mm, unit="mm")
        self.cylindrical = bool(cylindrical)
        self.centre_xy_mm, self.angle_rad, self.size_mm = plate_frame(self.outline_xy_mm)
        self.n_cells = np.maximum(np.ceil(self.size_mm / self.spacing_mm - 1e-9).astype(int), 1)
        self.knots_u = _knots(self.size_mm[0], self.n_cells[0])
        self.knots_v = _knots(self.size_mm[1], self.n_cells[1])
        self.n_u, self.n_v = self.n_cells[0] + DEGREE, self.n_cells[1] + DEGREE
        self.n_coef = self.n_u * self.n_v
        self._build_cells()
        self._build_dofs()

    # --- frames --------------------------------------------------------------------
    def to_plate(self, xy_mm) -> np.ndarray:
        """Plate u, v (n, 2) of press x, y (n, 2), mm."""
        return (np.asarray(xy_mm, dtype=float).reshape(-1, 2) - self.centre_xy_mm) @ rotation_2d(self.angle_rad)

    def to_press(self, uv_mm) -> np.ndarray:
        """Press x, y (n, 2) of plate u, v (n, 2), mm."""
        return np.asarray(uv_mm, dtype=float).reshape(-1, 2) @ rotation_2d(self.angle_rad).T + self.centre_xy_mm

    # --- evaluation ----------------------------------------------------------------
    def to_coef(self, q) -> np.ndarray:
        """B-spline coefficients (n_coef,) of the unknowns ``q`` (n_dof,) (0 where unused)."""
        return np.where(self.coef_dof >= 0, np.asarray(q, dtype=float)[np.maximum(self.coef_dof, 0)], 0.0)

    def evaluate(self, coef, uv_mm, du: int = 0, dv: int = 0) -> np.ndarray:
        """w (or a derivative) of coefficients ``coef`` (n_coef,) at plate points (m, 2)."""
        uv = np.asarray(uv_mm, dtype=float).reshape(-1, 2)
        spline = NdBSpline((self.knots_v, self.knots_u), np.asarray(coef, dtype=float).reshape(self.n_v, self.n_u),
                           DEGREE, extrapolate=True)
        return spline(uv[:, ::-1], nu=(dv, du))

    def point_blocks(self, uv_mm):
        """Local rows of w, w_u, w_v at plate points, for points in kept cells.

        Parameters
        ----------
        uv_mm : (m, 2) float

        Returns
        -------
        cell : (m,) int
            Kept cell of each point (-1: the point is in no kept cell).
        rows : (3, m, 16) float
            Weights of the cell's unknowns for w, w_u and w_v.
        """
        uv = np.asarray(uv_mm, dtype=float).reshape(-1, 2)
        eu = np.clip(np.searchsorted(self.knots_u[DEGREE:-DEGREE], uv[:, 0], side="right") - 1, 0, self.n_cells[0] - 1)
        ev = np.clip(np.searchsorted(self.knots_v[DEGREE:-DEGREE], uv[:, 1], side="right") - 1, 0, self.n_cells[1] - 1)
        cell = self._cell_index[ev, eu]
        local = np.arange(DEGREE + 1)
        rows = []
        for du, dv in ((0, 0), (1, 0), (0, 1)):
            bu = np.take_along_axis(basis(self.knots_u, uv[:, 0], du), eu[:, None] + local, axis=1)
            bv = np.take_along_axis(basis(self.knots_v, uv[:, 1], dv), ev[:, None] + local, axis=1)
            rows.append((bv[:, :, None] * bu[:, None, :]).reshape(len(uv), 16))
        return cell, np.stack(rows)

    def curvatures(self, q) -> np.ndarray:
        """kappa (g, 3) of the unknowns (n_dof,) at the Gauss points, 1/mm."""
        return np.einsum("gai,gi->ga", self.curvature, np.asarray(q)[self.gauss_dof])

    # --- assembly ------------------------------------------------------------------
    def assemble_vector(self, gauss_vectors) -> np.ndarray:
        """Sum of per-Gauss-point local vectors (g, 16) into a vector (n_dof,)."""
        per_cell = np.asarray(gauss_vectors).reshape(-1, 4, 16).sum(axis=1)
        return np.bincount(self.cell_dof.ravel(), per_cell.ravel(), minlength=self.n_dof)

    def band(self, blocks, cells) -> np.ndarray:
        """Sum of local matrices (k, 16, 16) of cells (k,) in symmetric band storage (bw + 1, n_dof)."""
        return self.band_of(self.band_slots(cells), blocks)

    def band_slots(self, *cells) -> np.ndarray:
        """Where the entries of local matrices of these cells (one or more (k,) arrays) go in band storage."""
        return np.concatenate([self._band_slot[c].ravel() for c in cells])

    def band_of(self, slots, *blocks) -> np.ndarray:
        """Sum of local matrices (arrays (k, 16, 16), in the order of :meth:`band_slots`) in band storage."""
        size = (self.bandwidth + 1) * self.n_dof
        values = np.concatenate([np.asarray(b).ravel() for b in blocks])
        return np.bincount(slots, values, minlength=size + 1)[:size].reshape(self.bandwidth + 1, self.n_dof)

    def gauss_band(self, gauss_matrices) -> np.ndarray:
        """Sum of per-Gauss-point matrices (g, 16, 16) in band storage (bw + 1, n_dof)."""
        per_cell = np.asarray(gauss_matrices).reshape(-1, 4, 16, 16).sum(axis=1)
        return self.band(per_cell, np.arange(len(self.cell_dof)))

    def mass_band(self) -> np.ndarray:
        """Integral of N^T N over the plate in band storage, mm^2."""
        vals = self.gauss_weight_mm2[:, None, None] * self.value[:, :, None] * self.value[:, None, :]
        return self.gauss_band(vals)

    def rigid_rows(self) -> np.ndarray:
        """(3, n_dof): the integrals of w, u w and v w over the plate (mm^2, mm^3) per unknown."""
        weight = self.gauss_weight_mm2[:, None] * self.value
        return np.stack([self.assemble_vector(weight * f[:, None])
                         for f in (np.ones(len(self.gauss_uv)), self.gauss_uv[:, 0], self.gauss_uv[:, 1])])

    def rigid_modes(self) -> np.ndarray:
        """(n_dof, 3): the unknowns of w = 1, w = u, w = v (Greville abscissae; w = v is 0 if cylindrical)."""
        greville_u = np.convolve(self.knots_u[1:-1], np.ones(DEGREE) / DEGREE, mode="valid")
        greville_v = np.convolve(self.knots_v[1:-1], np.ones(DEGREE) / DEGREE, mode="valid")
        iv, iu = np.divmod(np.arange(self.n_coef), self.n_u)
        modes = np.zeros((self.n_dof, 3))
        used = self.coef_dof >= 0
        v_mode = np.zeros(used.sum()) if self.cylindrical else greville_v[iv[used]]
        modes[self.coef_dof[used]] = np.column_stack([np.ones(used.sum()), greville_u[iu[used]], v_mode])
        return modes

    # --- construction ----------------------------------------------------------------
    def _build_cells(self):
        """Gauss points, weights and local operators of the cells inside the outline."""
        gu, wu, cu = _gauss(self.knots_u, self.n_cells[0])
        gv, wv, cv = _gauss(self.knots_v, self.n_cells[1])
        b_u = [basis(self.knots_u, gu, d) for d in range(3)]
        b_v = [basis(self.knots_v, gv, d) for d in range(3)]
        ev, eu = np.meshgrid(np.arange(self.n_cells[1]), np.arange(self.n_cells[0]), indexing="ij")
        iv = (2 * ev.ravel()[:, None] + np.array([0, 0, 1, 1])).ravel()
        iu = (2 * eu.ravel()[:, None] + np.array([0, 1, 0, 1])).ravel()
        uv = np.column_stack([gu[iu], gv[iv]])
        inside = contains(self.outline_xy_mm, self.to_press(uv), tolerance_mm=1e-9)
        keep_cell = inside.reshape(-1, 4).any(axis=1)
        self.cell_uv = np.column_stack([eu.ravel(), ev.ravel()])[keep_cell]
        self._cell_index = np.full(self.n_cells[::-1], -1)
        self._cell_index[self.cell_uv[:, 1], self.cell_uv[:, 0]] = np.arange(len(self.cell_uv))
        keep = np.repeat(keep_cell, 4)
        iu, iv, inside = iu[keep], iv[keep], inside[keep]
        self.gauss_uv = uv[keep]
        self.gauss_weight_mm2 = wu[iu] * wv[iv] * inside
        local = np.arange(DEGREE + 1)
        coef_u = cu[iu][:, None] + local
        coef_v = cv[iv][:, None] + local
        self._gauss_coef = (coef_v[:, :, None] * self.n_u + coef_u[:, None, :]).reshape(-1, 16)

        def outer(dv, du):
            a = np.take_along_axis(b_v[dv][iv], coef_v, axis=1)
            b = np.take_along_axis(b_u[du][iu], coef_u, axis=1)
            return (a[:, :, None] * b[:, None, :]).reshape(-1, 16)

        self.value = outer(0, 0)
        self.curvature = -np.stack([outer(0, 2), outer(2, 0), 2.0 * outer(1, 1)], axis=1)

    def _build_dofs(self):
        """Number the used coefficients along v first (or one per column); band slots of the cells."""
        cell_coef = self._gauss_coef[::4]
        used = np.zeros(self.n_coef, dtype=bool)
        used[cell_coef.ravel()] = True
        iv, iu = np.divmod(np.arange(self.n_coef), self.n_u)
        key = iu if self.cylindrical else iu * self.n_v + iv
        _, rank = np.unique(key[used], return_inverse=True)
        self.coef_dof = np.full(self.n_coef, -1)
        self.coef_dof[used] = rank
        self.n_dof = int(rank.max()) + 1
        self.gauss_dof = self.coef_dof[self._gauss_coef]
        self.cell_dof = self.gauss_dof[::4]
        rows = np.repeat(self.cell_dof[:, :, None], 16, axis=2)
        cols = np.repeat(self.cell_dof[:, None, :], 16, axis=1)
        self.bandwidth = int(np.max(np.abs(rows - cols)))
        dump = (self.bandwidth + 1) * self.n_dof
        self._band_slot = np.where(rows >= cols, (rows - cols) * self.n_dof + cols, dump)


def _knots(length_mm: float, n_cells: int) -> np.ndarray:
    """Clamped cubic knot vector over [-L/2, L/2] with ``n_cells`` equal cells."""
    inner = np.linspace(-0.5 * length_mm, 0.5 * length_mm, n_cells + 1)
    return np.concatenate([[inner[0]] * DEGREE, inner, [inner[-1]] * DEGREE])


def _gauss(knots: np.ndarray, n_cells: int):
    """Gauss points (2 per cell), their weights (mm) and each point's first coefficient index."""
    edges = knots[DEGREE:DEGREE + n_cells + 1]
    mid, half = 0.5 * (edges[1:] + edges[:-1]), 0.5 * (edges[1:] - edges[:-1])
    points = (mid[:, None] + half[:, None] * GAUSS_1D).ravel()
    weights = np.repeat(half, 2)
    first = np.repeat(np.arange(n_cells), 2)
    return points, weights, first
