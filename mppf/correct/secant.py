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

Smooth modes cannot follow what is local: the plate's edge rows and corners answer a stroke
change much more or much less than the interior (the free edge carries no moment across it,
the press gives most where the force is). So each punch also has a local ratio ``r`` of the
plate's change to the modal prediction ``p = G u``, a least-squares ratio over the punch and
its neighbours (weight :data:`NEIGHBOUR_WEIGHT`), pulled towards 1 by a prior of
:data:`LOCAL_PRIOR_MM` and held to :data:`LOCAL_RANGE`; older secants count
:data:`FORGET` as much as the next one. The plate's response to a model change ``u`` is
``r * (G u)`` (point by point).
"""

from __future__ import annotations

import numpy as np

from mppf.core.grid import neighbour_mean
from mppf.correct.punch_grid import PunchGrid

DEGREE = 4
"""Highest total degree of the polynomial modes."""

MIN_SECANT_MM = 0.3
"""RMS of the model's change below which a secant is not used (mm)."""

GAIN_RANGE = (0.4, 2.5)
"""Singular values of the response ratio are clipped to this range (what one secant may teach: a wider range,
that of :data:`mppf.correct.policy.RESPONSE_RANGE`, let a secant taken in the elastic stretch of a plate, where it
hardly moves, amplify the next request into a far worse cycle)."""

LOCAL_RANGE = (0.4, 2.5)
"""Range of the local response ratio of a punch."""

NEIGHBOUR_WEIGHT = 0.5
"""Weight of the 4-neighbours' mean in a punch's local least-squares ratio."""

LOCAL_PRIOR_MM = 0.5
"""Prior of the local ratio: as many secant points at 1 as a change of this size (mm)."""

FORGET = 0.5
"""Weight of the older secants in the local ratio, relative to the next one."""


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
        self._num = np.zeros(grid.shape)  # local ratio: sum of p v and of p^2 over the secants
        self._den = np.zeros(grid.shape)
        self.local = np.ones(grid.shape)

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
        self._update_local(m, p)
        return True

    def _update_local(self, m: np.ndarray, p: np.ndarray) -> None:
        """The local ratio of each punch after one more secant (``m`` model, ``p`` plate change at the active punches)."""
        act = self.grid.active
        modal = np.zeros(self.grid.shape)
        modal[act] = m + self.basis @ (self.matrix @ (self.basis.T @ m) - self.basis.T @ m)
        plate = np.zeros(self.grid.shape)
        plate[act] = p
        self._num = FORGET * self._num + modal * plate
        self._den = FORGET * self._den + modal**2

        def smooth(field):
            return field + NEIGHBOUR_WEIGHT * neighbour_mean(field, act)

        prior = LOCAL_PRIOR_MM**2
        ratio = (smooth(self._num) + prior) / (smooth(self._den) + prior)
        self.local = np.where(act, np.clip(ratio, *LOCAL_RANGE), 1.0)

    def model_request(self, wanted_mm) -> np.ndarray:
        """What to ask the model for so that the plate makes the change ``wanted_mm`` (rows, cols)."""
        act = self.grid.active
        w = (np.where(np.isfinite(wanted_mm), wanted_mm, 0.0) / self.local)[act]
        a = self.basis.T @ w
        out = np.zeros(self.grid.shape)
        out[act] = w + self.basis @ (np.linalg.solve(self.matrix, a) - a)
        return np.where(act, self.grid.flat(np.where(act, out, np.nan)), 0.0)

    def plate_response(self, model_change_mm) -> np.ndarray:
        """The change the plate is expected to make when the model makes ``model_change_mm`` (rows, cols)."""
        act = self.grid.active
        m = np.where(np.isfinite(model_change_mm), model_change_mm, 0.0)[act]
        a = self.basis.T @ m
        out = np.zeros(self.grid.shape)
        out[act] = (m + self.basis @ (self.matrix @ a - a)) * self.local[act]
        return np.where(act, self.grid.flat(np.where(act, out, np.nan)), 0.0)

    @property
    def gains(self) -> np.ndarray:
        """Singular values of ``G`` (1 = the plate responds as the model)."""
        return np.linalg.svd(self.matrix, compute_uv=False)
