"""The FE plate after a press step as the scanner sees it (the interface of ``FormedSteelPlate``).

The mid-surface is the mean of the plate's deformed bottom and top nodes of each node column.
Under large deflection the nodes also move in x, y (a bent plate's edges draw in), so heights
at press x, y are interpolated over the DEFORMED x, y of the columns (piecewise cubic,
Clough-Tocher, over their Delaunay triangulation); beyond the deformed edge the nearest column
gives the height. Normals are the interpolant's gradient, skins the mid-surface offset by the
local thickness along them (as :class:`mppf.sim.plate.formed.FormedSteelPlate`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mppf.sim.plate.formed import grid_inside
from scipy.interpolate import CloughTocher2DInterpolator, NearestNDInterpolator

SLOPE_STEP_MM = 1.0
"""Half step of the central differences of the normals, mm."""


class MidSurface:
    """Height z(x, y) of a deformed mid-surface given by points (n, 3), mm."""

    def __init__(self, points_mm: np.ndarray):
        self.points_mm = np.asarray(points_mm, dtype=float)
        self._smooth = CloughTocher2DInterpolator(self.points_mm[:, :2], self.points_mm[:, 2])
        self._nearest = NearestNDInterpolator(self.points_mm[:, :2], self.points_mm[:, 2])

    def __call__(self, xy_mm) -> np.ndarray:
        """Heights (n,) at press x, y (n, 2), mm."""
        xy = np.asarray(xy_mm, dtype=float).reshape(-1, 2)
        z = self._smooth(xy)
        bad = ~np.isfinite(z)
        if bad.any():
            z[bad] = self._nearest(xy[bad])
        return z


@dataclass(frozen=True, eq=False)
class FormedFEPlate:
    """An FE plate after a press step, in press coordinates (mm).

    Attributes
    ----------
    outline_xy_mm : (k, 2) float
        The plate's outline (as cut) in press x, y.
    plate : PhysicalPlate
        The true steel, thickness and scatter fields.
    loaded_mid_mm, unloaded_mid_mm : (n, 3) float
        Deformed mid-surface points of the node columns, loaded (end of the step's load) and free.
    contact_xyz_mm : (m, 3) float
        Loaded mid-surface at the axes of the punch pairs that pushed.
    lower_force_n, upper_force_n : (rows, cols) float
        Contact force of each lower / upper ball at the end of loading, N (NaN off the plate).
    to_plate : callable
        Plate u, v (n, 2) of press x, y (n, 2) (the scatter fields' frame).
    """

    outline_xy_mm: np.ndarray
    plate: object
    loaded_mid_mm: np.ndarray
    unloaded_mid_mm: np.ndarray
    contact_xyz_mm: np.ndarray
    lower_force_n: np.ndarray
    upper_force_n: np.ndarray
    to_plate: object

    def __post_init__(self):
        object.__setattr__(self, "_loaded", MidSurface(self.loaded_mid_mm))
        object.__setattr__(self, "_unloaded", MidSurface(self.unloaded_mid_mm))

    @property
    def thickness_mm(self) -> float:
        """True mean thickness of the plate, mm."""
        return self.plate.thickness_mm

    def thickness_at(self, xy_mm) -> np.ndarray:
        """True local thickness (m,) at press positions (m, 2), mm."""
        return self.plate.thickness_at(self.to_plate(xy_mm))

    def height_mm(self, x_mm, y_mm, *, loaded: bool = False) -> np.ndarray:
        """Mid-surface height z at press positions (x, y) (any matching shapes), mm."""
        x, y = np.broadcast_arrays(np.asarray(x_mm, dtype=float), np.asarray(y_mm, dtype=float))
        surface = self._loaded if loaded else self._unloaded
        return surface(np.column_stack([x.ravel(), y.ravel()])).reshape(x.shape)

    def sample_xy(self, spacing_mm: float) -> np.ndarray:
        """Press (x, y) (n, 2) of a regular grid of ``spacing_mm`` inside the outline (:func:`grid_inside`)."""
        return grid_inside(self.outline_xy_mm, spacing_mm)

    def mid_surface_points(self, spacing_mm: float = 20.0, *, loaded: bool = False) -> np.ndarray:
        """Mid-surface points (n, 3) on a regular x, y grid inside the outline, mm."""
        xy = self.sample_xy(spacing_mm)
        return np.column_stack([xy, self.height_mm(xy[:, 0], xy[:, 1], loaded=loaded)])

    def skin_points(self, spacing_mm: float = 20.0, side: float = 1.0) -> np.ndarray:
        """Skin points (n, 3) of the free plate: mid-surface + ``side`` * local t/2 along the normal."""
        xy = self.sample_xy(spacing_mm)
        return self.offset_points(xy, side * 0.5 * self.thickness_mm)

    def top_skin_points(self, spacing_mm: float = 20.0) -> np.ndarray:
        """Top-skin points (n, 3) of the free plate with its local thickness, mm."""
        return self.skin_points(spacing_mm, side=1.0)

    def offset_points(self, xy_mm, offset_mm: float) -> np.ndarray:
        """Free mid-surface points above ``xy_mm`` (m, 2) moved ``offset_mm * t_local / t_mean`` along the normal.

        Returns
        -------
        (m, 3) float, press coordinates, mm
        """
        xy = np.asarray(xy_mm, dtype=float).reshape(-1, 2)
        local = offset_mm * self.thickness_at(xy) / self.thickness_mm
        z = self._unloaded(xy)
        return np.column_stack([xy, z]) + local[:, None] * self.normals(xy)

    def normals(self, xy_mm) -> np.ndarray:
        """Unit up normals (m, 3) of the free mid-surface above ``xy_mm`` (m, 2)."""
        xy = np.asarray(xy_mm, dtype=float).reshape(-1, 2)
        h = SLOPE_STEP_MM
        dx, dy = np.array([h, 0.0]), np.array([0.0, h])
        wx = (self._unloaded(xy + dx) - self._unloaded(xy - dx)) / (2 * h)
        wy = (self._unloaded(xy + dy) - self._unloaded(xy - dy)) / (2 * h)
        normal = np.column_stack([-wx, -wy, np.ones(len(xy))])
        return normal / np.linalg.norm(normal, axis=1, keepdims=True)
