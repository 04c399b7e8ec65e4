"""Fields on the press's punch grid: filled where no punch acts, their curvatures, and heights from curvatures.

The learned correction (:mod:`mppf.correct.learned`) works point by point in curvature: the
loaded curvature of a step is that of the tips' mid heights, the formed plate's that of the
design plus the measured deviation. :class:`PunchGrid` holds the press's punch axes and the
punches in use and three linear maps, built once per grid as matrices:

- ``fill``: values at the active punches -> the whole grid (a thin-plate spline,
  :func:`mppf.core.grid.tps_fill`);
- ``curvature``: heights on the grid -> (z_xx, z_yy, 2 z_xy) at every punch
  (:func:`mppf.core.grid.hessian`);
- ``heights``: a curvature field -> the heights at the active punches that best have it
  (:func:`mppf.core.grid.integrate_hessian`), their best plane over the active punches
  removed (a scan fixes no rigid placement).

Fields are (rows, cols) arrays (NaN where inactive); curvatures are (m, 3) arrays at the m
active punches.
"""

from __future__ import annotations

import numpy as np

from mppf.core.grid import hessian, integrate_hessian, tps_fill
from mppf.model.press import PressConfig


class PunchGrid:
    """The punch grid of a press and the punches acting on the plate.

    Parameters
    ----------
    press : PressConfig
    active : (rows, cols) bool
        Punches acting on the plate (at least 3, not in one line).
    """

    def __init__(self, press: PressConfig, active):
        self.press = press
        self.active = np.asarray(active, dtype=bool)
        self.x_mm, self.y_mm = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
        xy = np.column_stack([self.x_mm.ravel(), self.y_mm.ravel()])
        self.index = np.flatnonzero(self.active.ravel())
        n = xy.shape[0]
        # fill: (n, m) thin-plate spline from the active punches to every punch
        self.fill_matrix = tps_fill(xy[self.index], np.eye(len(self.index)), xy)
        # curvature: (3 n, n), rows point by point (z_xx, z_yy, 2 z_xy)
        self.curvature_matrix = np.empty((3 * n, n))
        for j, unit in enumerate(np.eye(n).reshape(n, *self.active.shape)):
            zxx, zxy, zyy = hessian(unit, press.pitch_x_mm, press.pitch_y_mm)
            self.curvature_matrix[:, j] = np.column_stack([zxx.ravel(), zyy.ravel(), 2.0 * zxy.ravel()]).ravel()
        # heights: (m, 3 m) from the active punches' curvature (filled beyond them), best plane removed
        a = np.column_stack([np.ones(len(self.index)), xy[self.index]])
        self.plane_free = np.eye(len(self.index)) - a @ np.linalg.pinv(a)
        extend = np.kron(self.fill_matrix, np.eye(3))  # (3 n, 3 m): each component filled
        self.heights_matrix = self.plane_free @ (self._integration()[self.index] @ extend)
        # curvature at the active punches of heights there (filled beyond them): (3 m, m)
        rows = (3 * self.index[:, None] + np.arange(3)).ravel()
        self.stroke_curvature = (self.curvature_matrix @ self.fill_matrix)[rows]

    @property
    def shape(self) -> tuple[int, int]:
        return self.active.shape

    def _integration(self) -> np.ndarray:
        """(n, 3 n): heights on the whole grid from a curvature field (least squares)."""
        n = self.active.size
        hx, hy = self.press.pitch_x_mm, self.press.pitch_y_mm
        out = np.empty((n, 3 * n))
        zero = np.zeros(self.shape)
        for j in range(3 * n):
            point, comp = divmod(j, 3)
            fields = [zero.copy(), zero.copy(), zero.copy()]  # k_xx, k_yy, 2 k_xy
            fields[comp].ravel()[point] = 1.0
            out[:, j] = integrate_hessian(fields[0], 0.5 * fields[2], fields[1], hx, hy).ravel()
        return out

    def active_values(self, field) -> np.ndarray:
        """The (m,) values of a (rows, cols) field at the active punches; unknown (NaN) ones from the known."""
        values = np.asarray(field, dtype=float).ravel()[self.index]
        known = np.isfinite(values)
        if known.all() or known.sum() < 3:
            return np.where(known, values, 0.0)
        xy = np.column_stack([self.x_mm.ravel(), self.y_mm.ravel()])[self.index]
        return np.where(known, values, 0.0) + np.where(known, 0.0, 1.0) * np.where(
            known, 0.0, tps_fill(xy[known], values[known], xy))

    def to_field(self, values) -> np.ndarray:
        """(m,) values at the active punches as a (rows, cols) field, NaN elsewhere."""
        out = np.full(self.active.size, np.nan)
        out[self.index] = values
        return out.reshape(self.shape)

    def fill(self, field) -> np.ndarray:
        """A (rows, cols) field given at the active punches, over the whole grid (rows, cols)."""
        return (self.fill_matrix @ self.active_values(field)).reshape(self.shape)

    def curvature(self, field) -> np.ndarray:
        """Curvature (m, 3) at the active punches of a field given there (filled beyond them first)."""
        return (self.stroke_curvature @ self.active_values(field)).reshape(-1, 3)

    def heights(self, kappa) -> np.ndarray:
        """Heights at the active punches (rows, cols; NaN elsewhere) that best have curvature ``kappa`` (m, 3)."""
        return self.to_field(self.heights_matrix @ np.asarray(kappa, dtype=float).reshape(-1))

    def flat(self, field) -> np.ndarray:
        """A field at the active punches with its best plane removed (rows, cols; NaN elsewhere)."""
        return self.to_field(self.plane_free @ self.active_values(field))
