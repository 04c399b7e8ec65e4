"""The formed steel plate as the scanner sees it (same interface as ``sim.forming.FormedPlate``).

Heights come from the plate's B-spline mid-surface (exact, no resampling). The skins are
the mid-surface offset along its unit up normal by half the LOCAL thickness: an offset
given in mm is taken at the plate's mean thickness ``thickness_mm`` and scales with the
local thickness, ``offset_points(xy, h)`` = mid + h t(x, y) / thickness_mm n. So
``offset_points(xy, thickness_mm / 2)``, what :class:`mppf.sim.scanner.SimulatedScanner`
asks for, is the real top skin, and ``-thickness_mm / 2`` the real bottom skin.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.errors import InputError
from mppf.core.polygon import contains

SAMPLE_SPACING_MM = 20.0
"""Spacing of the press-aligned arrays ``x_mm``, ``y_mm`` of the height fields."""


def grid_inside(outline_xy_mm, spacing_mm: float) -> np.ndarray:
    """Press (x, y) (n, 2) of a regular grid of ``spacing_mm`` (mm) inside the outline (k, 2) (mm).

    The grid is centred on the outline's bounding box, so the rows and columns left over at the
    edges are the same on both sides (a grid starting at one edge would sample that edge and stop up
    to a spacing short of the other: a scan whose edge seems shifted).
    """
    if not np.isfinite(spacing_mm) or spacing_mm <= 0:
        raise InputError(f"the sampling spacing must be a positive number of mm, got {spacing_mm}",
                         hint="give a spacing such as 20 mm")
    outline = np.asarray(outline_xy_mm, dtype=float)
    lo, hi = outline.min(axis=0), outline.max(axis=0)
    count = np.floor((hi - lo) / spacing_mm + 1e-9).astype(int)
    start = 0.5 * (lo + hi) - 0.5 * count * spacing_mm
    xx, yy = np.meshgrid(start[0] + spacing_mm * np.arange(count[0] + 1),
                         start[1] + spacing_mm * np.arange(count[1] + 1))
    xy = np.column_stack([xx.ravel(), yy.ravel()])
    return xy[contains(outline, xy, tolerance_mm=1e-6)]


@dataclass(frozen=True, eq=False)
class FormedSteelPlate:
    """A steel plate after a press step, in press coordinates (mm).

    Attributes
    ----------
    x_mm : (nx,) float
    y_mm : (ny,) float
        Press-aligned sampling of the bounding box of the outline.
    loaded_z_mm : (ny, nx) float
        Mid-surface while held between the punches (at the end of the last step); NaN
        outside the outline.
    unloaded_z_mm : (ny, nx) float
        Mid-surface after springback; NaN outside the outline.
    outline_xy_mm : (k, 2) float
        The plate's outline in press x, y.
    plate : PhysicalPlate
        The true steel, thickness and scatter fields.
    contact_xyz_mm : (m, 3) float
        Loaded mid-surface at the axes of the punch pairs that pushed (force > 0).
    lower_force_n, upper_force_n : (rows, cols) float
        Contact force of each lower / upper punch at the end of loading, N (0 where it
        did not touch, NaN off the plate).
    mean_ratio : float
        Unloaded / loaded curvature (RMS over the plate); 1 = no springback.
    grid : PlateGrid
    loaded_coef, unloaded_coef : (n_coef,) float
        B-spline coefficients of the two mid-surfaces.
    """

    x_mm: np.ndarray
    y_mm: np.ndarray
    loaded_z_mm: np.ndarray
    unloaded_z_mm: np.ndarray
    outline_xy_mm: np.ndarray
    plate: object
    contact_xyz_mm: np.ndarray
    lower_force_n: np.ndarray
    upper_force_n: np.ndarray
    mean_ratio: float
    grid: object
    loaded_coef: np.ndarray
    unloaded_coef: np.ndarray

    @classmethod
    def build(cls, grid, plate, loaded_q, unloaded_q, punches, force_n) -> FormedSteelPlate:
        """The formed plate of a grid, its unknowns (n_dof,) loaded and unloaded, the forces (2 m,) N."""
        loaded_coef, unloaded_coef = grid.to_coef(loaded_q), grid.to_coef(unloaded_q)
        lo, hi = grid.outline_xy_mm.min(axis=0), grid.outline_xy_mm.max(axis=0)
        x = np.linspace(lo[0], hi[0], int(np.ceil((hi[0] - lo[0]) / SAMPLE_SPACING_MM)) + 1)
        y = np.linspace(lo[1], hi[1], int(np.ceil((hi[1] - lo[1]) / SAMPLE_SPACING_MM)) + 1)
        xx, yy = np.meshgrid(x, y)
        xy = np.column_stack([xx.ravel(), yy.ravel()])
        inside = contains(grid.outline_xy_mm, xy, tolerance_mm=1e-6)
        uv = grid.to_plate(xy)
        m = punches.count
        pushed = (force_n[:m] > 0) | (force_n[m:] > 0)
        z_contact = punches.mid_surface_mm(loaded_q)
        kappa_l, kappa_u = grid.curvatures(loaded_q), grid.curvatures(unloaded_q)
        weight = grid.gauss_weight_mm2
        loaded_norm = float(np.sum(weight * np.sum(kappa_l**2, axis=1)))
        ratio = float(np.sqrt(np.sum(weight * np.sum(kappa_u**2, axis=1)) / loaded_norm)) if loaded_norm > 0 else 1.0
        return cls(
            x_mm=x, y_mm=y,
            loaded_z_mm=np.where(inside, grid.evaluate(loaded_coef, uv), np.nan).reshape(xx.shape),
            unloaded_z_mm=np.where(inside, grid.evaluate(unloaded_coef, uv), np.nan).reshape(xx.shape),
            outline_xy_mm=grid.outline_xy_mm, plate=plate,
            contact_xyz_mm=np.column_stack([punches.xy_mm[pushed], z_contact[pushed]]),
            lower_force_n=punches.spread(force_n[:m]), upper_force_n=punches.spread(force_n[m:]),
            mean_ratio=ratio, grid=grid, loaded_coef=loaded_coef, unloaded_coef=unloaded_coef,
        )

    @property
    def thickness_mm(self) -> float:
        """True mean thickness of the plate, mm."""
        return self.plate.thickness_mm

    def thickness_at(self, xy_mm) -> np.ndarray:
        """True local thickness (m,) at press positions (m, 2), mm."""
        return self.plate.thickness_at(self.grid.to_plate(xy_mm))

    def height_mm(self, x_mm, y_mm, *, loaded: bool = False) -> np.ndarray:
        """Mid-surface height z at press positions (x, y) (any matching shapes), mm."""
        x, y = np.broadcast_arrays(np.asarray(x_mm, dtype=float), np.asarray(y_mm, dtype=float))
        coef = self.loaded_coef if loaded else self.unloaded_coef
        uv = self.grid.to_plate(np.column_stack([x.ravel(), y.ravel()]))
        return self.grid.evaluate(coef, uv).reshape(x.shape)

    def sample_xy(self, spacing_mm: float) -> np.ndarray:
        """Press (x, y) (n, 2) of a regular grid of ``spacing_mm`` inside the outline (:func:`grid_inside`)."""
        return grid_inside(self.outline_xy_mm, spacing_mm)

    def mid_surface_points(self, spacing_mm: float = SAMPLE_SPACING_MM, *, loaded: bool = False) -> np.ndarray:
        """Mid-surface points (n, 3) on a regular x, y grid inside the outline, mm."""
        xy = self.sample_xy(spacing_mm)
        return np.column_stack([xy, self.height_mm(xy[:, 0], xy[:, 1], loaded=loaded)])

    def skin_points(self, spacing_mm: float = SAMPLE_SPACING_MM, side: float = 1.0) -> np.ndarray:
        """Skin points (n, 3) of the unloaded plate: mid-surface + ``side`` * local t/2 along the normal.

        ``side`` = +1 top skin, -1 bottom skin, 0 mid-surface.
        """
        xy = self.sample_xy(spacing_mm)
        return self.offset_points(xy, side * 0.5 * self.thickness_mm)

    def top_skin_points(self, spacing_mm: float = SAMPLE_SPACING_MM) -> np.ndarray:
        """Top-skin points (n, 3) of the unloaded plate with its local thickness, mm."""
        return self.skin_points(spacing_mm, side=1.0)

    def offset_points(self, xy_mm, offset_mm: float) -> np.ndarray:
        """Unloaded mid-surface points above ``xy_mm`` (m, 2) moved along the up normal.

        The move is ``offset_mm * t_local / thickness_mm``: ``offset_mm`` is measured at the
        mean thickness, so +-thickness_mm / 2 lands on the real local skins.

        Returns
        -------
        (m, 3) float, press coordinates, mm
        """
        xy = np.asarray(xy_mm, dtype=float).reshape(-1, 2)
        local = offset_mm * self.thickness_at(xy) / self.thickness_mm
        z = self.height_mm(xy[:, 0], xy[:, 1])
        return np.column_stack([xy, z]) + local[:, None] * self.normals(xy)

    def normals(self, xy_mm) -> np.ndarray:
        """Unit up normals (m, 3) of the unloaded mid-surface above ``xy_mm`` (m, 2)."""
        xy = np.asarray(xy_mm, dtype=float).reshape(-1, 2)
        uv = self.grid.to_plate(xy)
        wu = self.grid.evaluate(self.unloaded_coef, uv, du=1)
        wv = self.grid.evaluate(self.unloaded_coef, uv, dv=1)
        c, s = np.cos(self.grid.angle_rad), np.sin(self.grid.angle_rad)
        wx, wy = c * wu - s * wv, s * wu + c * wv
        normal = np.column_stack([-wx, -wy, np.ones(len(xy))])
        return normal / np.linalg.norm(normal, axis=1, keepdims=True)
