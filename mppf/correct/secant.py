"""How the plate responds compared with the model: a Broyden update of the response in smooth modes.

The calibrated model (:mod:`mppf.correct.calibrate`) has two parameters; the plate answers
to the strokes in ways two parameters cannot follow (its edges, the press's give, its
anisotropy). Each pair of measured cycles shows one secant: the plate's measured change
``v`` against the model's change ``u`` for the same strokes. In a basis of smooth modes on
the punch grid (polynomials up to :data:`DEGREE` over the active punches, plane excluded,
orthonormal) the ratio of the plate's response to the model's is a matrix ``G``, the
identity until data come, updated by Broyden's rank-one rule after every secant::

    G <- G + (v - G u) u^T / (u^T u)

(only secants larger than :data:`MIN_SECANT_MM`: smaller ones are noise). The correction asks
the model for ``G^-1`` times the change it wants the plate to make; ``G``'s singular values
are held to :data:`GAIN_RANGE` (a trust region on what one secant may teach).
"""

from __future__ import annotations

import numpy as np

from mppf.correct.punch_grid import PunchGrid

DEGREE = 4
"""Highest total degree of the polynomial modes."""

MIN_SECANT_MM = 0.3
"""RMS of the model's change below which a secant is not used (mm)."""

GAIN_RANGE = (0.4, 2.5)
"""Singular values of the response ratio are clipped to this range."""


class ModeGain:
    """The response ratio ``G`` of the plate to the model in smooth modes of one punch grid.

    Parameters
    ----------
    grid : PunchGrid
    """

    def __init__(self, grid: PunchGrid):
        act = grid.active
        x, y = grid.x_mm[act], grid.y_mm[act]
        u = (x - x.mean()) / max(np.ptp(x), 1.0) * 2.0
        v = (y - y.mean()) / max(np.ptp(y), 1.0) * 2.0
        columns = [np.ones_like(u), u, v]
        columns += [u**i * v**(d - i) for d in range(2, DEGREE + 1) for i in range(d + 1)]
        q, _ = np.linalg.qr(np.column_stack(columns))
        self.grid = grid
        self.basis = q[:, 3:]  # orthonormal over the active punches, plane removed
        self.matrix = np.eye(self.basis.shape[1])
        self.updates = 0

    def update(self, model_change_mm, plate_change_mm) -> bool:
        """One Broyden update from a secant (height changes at the punches, (rows, cols)); False when too small."""
        act = self.grid.active
        m = np.where(np.isfinite(model_change_mm), model_change_mm, 0.0)[act]
        p = np.where(np.isfinite(plate_change_mm), plate_change_mm, 0.0)[act]
        if np.sqrt(np.mean(m**2)) < MIN_SECANT_MM:
            return False
        u, v = self.basis.T @ m, self.basis.T @ p
        self.matrix = self.matrix + np.outer(v - self.matrix @ u, u) / float(u @ u)
        left, values, right = np.linalg.svd(self.matrix)
        self.matrix = left @ np.diag(np.clip(values, *GAIN_RANGE)) @ right
        self.updates += 1
        return True

    def model_request(self, wanted_mm) -> np.ndarray:
        """What to ask the model for so that the plate makes the change ``wanted_mm`` (rows, cols)."""
        act = self.grid.active
        w = np.where(np.isfinite(wanted_mm), wanted_mm, 0.0)[act]
        a = self.basis.T @ w
        out = np.zeros(self.grid.shape)
        out[act] = w + self.basis @ (np.linalg.solve(self.matrix, a) - a)
        return out

    def plate_response(self, model_change_mm) -> np.ndarray:
        """The change the plate is expected to make when the model makes ``model_change_mm`` (rows, cols)."""
        act = self.grid.active
        m = np.where(np.isfinite(model_change_mm), model_change_mm, 0.0)[act]
        a = self.basis.T @ m
        out = np.zeros(self.grid.shape)
        out[act] = m + self.basis @ (self.matrix @ a - a)
        return out

    @property
    def gains(self) -> np.ndarray:
        """Singular values of ``G`` (1 = the plate responds as the model)."""
        return np.linalg.svd(self.matrix, compute_uv=False)
