"""Punch contact and press-frame compliance.

Every punch pair whose axis lies over the plate is a pair of unilateral constraints on
the mid-surface (ball tips of radius ``r``, the plate locally planar with slope ``grad w``
and thickness ``t`` at the axis, ``s = sqrt(1 + |grad w|^2)``, ``rho = r + t/2``)::

    lower:  g_l = w - L - t/2 - rho (s - 1) >= 0     (ball centre at L - r, distance >= rho)
    upper:  g_u = U - t/2 - rho (s - 1) - w >= 0     (ball centre at U + r)

with ``L, U`` the tip heights the PLC read back.

Compliance: the tips are not where the PLC reads them. Each matrix deflects as a bowl
``delta b_i`` (lower matrix down, upper matrix up, ``b = 1 - 0.5 ((x / X)^2 + (y / Y)^2)``:
1 at the bed centre, 1/2 at its corners, ``X, Y`` the half sizes of the punch matrix) with
``delta = c_frame sum_j b_j f_j`` (the frame as one spring loaded through the bowl), and
each punch gives locally by ``c_punch f``. A constraint's contact force is therefore
that of a spring on its penetration::

    f = max(0, -(g + b delta)) / c_punch

so the contact is unilateral (no force while the gap is open) and the deflections satisfy
``g + G f >= 0`` with the symmetric compliance matrix ``G = c_punch I + c_frame b b^T``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.errors import InputError
from mppf.core.polygon import contains
from mppf.core.validate import check_number

NUMERICAL_COMPLIANCE_MM_PER_N = 1e-7
"""Smallest punch compliance (mm/N, 0.1 um/kN): keeps a pair squeezing the plate solvable."""


def refuse_crushing(gap_mm, thickness_mm, index) -> None:
    """Refuse a step whose tips close to less than half the plate's thickness over any pair.

    Parameters
    ----------
    gap_mm : ndarray (m,)
        Upper minus lower tip height of each pair over the plate (mm; ``inf`` where the pair is not active).
    thickness_mm : ndarray (m,) or float
        The plate's thickness at each pair (mm).
    index : ndarray (m, 2) of int
        Each pair's (row, col) on the press.

    Raises
    ------
    InputError
        At the pair that closes most, naming its row, column, gap and the thickness.
    """
    gap_mm = np.asarray(gap_mm, dtype=float)
    half_mm = 0.5 * np.asarray(thickness_mm, dtype=float) * np.ones_like(gap_mm)
    if np.any(gap_mm < half_mm):
        i = int(np.argmin(gap_mm - half_mm))
        row, col = (int(k) for k in index[i])
        raise InputError(f"the gap between upper and lower tips is {gap_mm[i]:.3f} mm at punch (row {row}, "
                         f"col {col}), less than half the plate thickness {2 * half_mm[i]:.3f} mm",
                         hint="the step would crush the plate; check the strokes")


@dataclass(frozen=True)
class Compliance:
    """Elastic give of the press under the forming forces.

    Attributes
    ----------
    frame_mm_per_mn : float
        Deflection of each matrix at the bed centre per MN of bowl-weighted force
        ``sum_j b_j f_j`` on it (lower matrix down, upper matrix up), mm/MN.
    punch_mm_per_kn : float
        Local give of one punch (rod, ball, seat) per kN of its own force, mm/kN.
    """

    frame_mm_per_mn: float = 0.5
    punch_mm_per_kn: float = 0.01

    def __post_init__(self):
        check_number("frame compliance", self.frame_mm_per_mn, low=0.0, high=100.0, unit="mm/MN")
        check_number("punch compliance", self.punch_mm_per_kn, low=0.0, high=1.0, unit="mm/kN")

    @property
    def frame_mm_per_n(self) -> float:
        """Frame compliance, mm/N."""
        return self.frame_mm_per_mn * 1e-6

    @property
    def punch_mm_per_n(self) -> float:
        """Punch compliance with the numerical floor, mm/N."""
        return max(self.punch_mm_per_kn * 1e-3, NUMERICAL_COMPLIANCE_MM_PER_N)


RIGID = Compliance(frame_mm_per_mn=0.0, punch_mm_per_kn=0.0)
"""A press that does not give (closed-form checks)."""


class Punches:
    """The punch pairs over a plate and their constraints.

    A pair takes part when its axis lies inside the outline and in a kept cell of the
    grid (this leaves out axes within a quarter cell of a trimmed edge).

    Parameters
    ----------
    press : PressConfig
    grid : PlateGrid
    thickness_at : callable
        Local thickness (n,) mm at plate points (n, 2).
    placement_mm : (2,) float
        Where the press's punch axes lie in the plate's frame (press x, y of the first placement), mm: the
        shift of the plate between sections of a plate larger than the bed (0: the plate as first laid).

    Attributes
    ----------
    index : (m, 2) int
        (row, col) of each punch pair over the plate.
    xy_mm : (m, 2) float
        Their axes in the plate's frame (press x, y of the first placement, shifted by ``placement_mm``).
    thickness_mm : (m,) float
        Plate thickness at the axes.
    bowl : (m,) float
        Bowl factor b of the frame deflection.
    cell : (m,) int
        Grid cell of each axis.
    rows : (3, m, 16) float
        Local rows of w, w_u, w_v at the axes.
    """

    def __init__(self, press, grid, thickness_at, placement_mm=(0.0, 0.0)):
        px, py = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
        on_press = np.column_stack([px.ravel(), py.ravel()])
        xy = on_press + np.asarray(placement_mm, dtype=float).reshape(1, 2)
        cell, rows = grid.point_blocks(grid.to_plate(xy))
        over = contains(grid.outline_xy_mm, xy, tolerance_mm=1e-9) & (cell >= 0)
        self.shape = press.shape
        self.index = np.column_stack(np.divmod(np.nonzero(over)[0], press.cols))
        self.xy_mm = xy[over]
        self.cell, self.rows = cell[over], rows[:, over]
        self.dof = grid.cell_dof[self.cell]
        self.thickness_mm = thickness_at(grid.to_plate(self.xy_mm))
        self.radius_mm = press.tip_radius_mm
        half = np.array([max(np.ptp(press.punch_x_mm), 1.0), max(np.ptp(press.punch_y_mm), 1.0)]) / 2
        centre = np.array([press.punch_x_mm.mean(), press.punch_y_mm.mean()])
        self.bowl = 1.0 - 0.5 * np.sum(((on_press[over] - centre) / half) ** 2, axis=1)  # the frame's, on the press
        self.n_dof = grid.n_dof

    @property
    def count(self) -> int:
        """Number of punch pairs over the plate."""
        return len(self.index)

    def pick(self, grid_values) -> np.ndarray:
        """Values (m,) of a (rows, cols) press grid at the punch pairs over the plate."""
        return np.asarray(grid_values)[self.index[:, 0], self.index[:, 1]]

    def spread(self, values, fill=np.nan) -> np.ndarray:
        """A (rows, cols) press grid with ``values`` (m,) at the pairs over the plate."""
        out = np.full(self.shape, fill, dtype=float)
        out[self.index[:, 0], self.index[:, 1]] = values
        return out

    def mid_surface_mm(self, q) -> np.ndarray:
        """The mid-surface (m,) at the punch axes of the unknowns ``q`` (n_dof,), mm."""
        return np.sum(self.rows[0] * np.asarray(q)[self.dof], axis=1)

    def gaps(self, q, lower_mm, upper_mm) -> tuple[np.ndarray, np.ndarray]:
        """Gaps of the lower and upper constraints and their local Jacobian rows.

        Parameters
        ----------
        q : (n_dof,) float
            The plate's unknowns.
        lower_mm, upper_mm : (m,) float
            Tip heights the PLC read back, mm.

        Returns
        -------
        gap_mm : (2 m,) float
            ``g_l`` of every pair, then ``g_u``.
        jacobian : (2 m, 16) float
            d gap / d (the unknowns of the pair's cell, :attr:`dof` twice).
        """
        local = np.asarray(q)[self.dof]
        w, wu, wv = np.sum(self.rows * local, axis=2)
        s = np.sqrt(1.0 + wu**2 + wv**2)
        rho = self.radius_mm + 0.5 * self.thickness_mm
        tilt = rho * (s - 1.0)
        gap = np.concatenate([w - lower_mm - 0.5 * self.thickness_mm - tilt,
                              upper_mm - 0.5 * self.thickness_mm - tilt - w])
        slope = (rho * wu / s)[:, None] * self.rows[1] + (rho * wv / s)[:, None] * self.rows[2]
        return gap, np.concatenate([self.rows[0] - slope, -self.rows[0] - slope])

    def transpose_times(self, jacobian, force_n) -> np.ndarray:
        """J^T f (n_dof,) of local Jacobian rows (2 m, 16) and forces (2 m,)."""
        dof = np.concatenate([self.dof, self.dof])
        return np.bincount(dof.ravel(), (jacobian * np.asarray(force_n)[:, None]).ravel(), minlength=self.n_dof)

    def tilt_blocks(self, q, force_n) -> np.ndarray:
        """Local blocks (m, 16, 16) of sum f d^2(-g)/dq^2, N/mm: the tilt terms in the Newton matrix.

        Both constraints of a pair have the term ``-rho (s - 1)``; ``s`` is convex in the slope,
        so the blocks are positive semi-definite for pushing forces.
        """
        m = self.count
        local = np.asarray(q)[self.dof]
        _, wu, wv = np.sum(self.rows * local, axis=2)
        s = np.sqrt(1.0 + wu**2 + wv**2)
        f = np.asarray(force_n, dtype=float)
        weight = (self.radius_mm + 0.5 * self.thickness_mm) * (f[:m] + f[m:]) / s
        du, dv = self.rows[1], self.rows[2]
        slope = (wu / s)[:, None] * du + (wv / s)[:, None] * dv

        def outer(a, b):
            return a[:, :, None] * b[:, None, :]

        return weight[:, None, None] * (outer(du, du) + outer(dv, dv) - outer(slope, slope))
