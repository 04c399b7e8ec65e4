"""Start of a load increment: the elastic plate's contact problem, solved on the punch axes.

Which punch of a pair holds the plate (lower, upper, both when the gap is closed, or
neither when it is open) is the hard part of the loaded equilibrium. The predictor
solves it for an elastic plate moving from a reference equilibrium (the last loaded state,
forces ``f_ref``), in the space of the pairs' net upward forces ``f`` (m,):

    w = w_ref + C (f - f_ref) + Phi a,      Phi^T f = -Phi^T f_weight,      f = f_lower - f_upper

with the elastic flexibility ``C`` (m, m) of the axes (the plate on three stiff supports,
computed once per plate), the rigid modes ``Phi`` (1, u, v at the axes) and their
amplitudes ``a``. Each side of a pair is a constraint with its own force (both push where
the gap is closed), with the limits ``lo = L + t/2 + tilt`` and ``hi = U - t/2 - tilt`` (the
tilt at the reference slope, then again at the predicted one)::

    lower side:  w = lo - c_p f_lower  (f_lower > 0)  or  w >= lo, f_lower = 0
    upper side:  w = hi + c_p f_upper  (f_upper > 0)  or  w <= hi, f_upper = 0

The limits move with the matrices' bowl deflections ``delta = c_f B^T f_side`` (two more
unknowns). A primal-dual active set on the pairs' states (dense, a few milliseconds per
iteration) gives the states, the elastic shape and deflections, and so the Newton
solver's start and first active set.
"""

from __future__ import annotations

import numpy as np

from mppf.sim.plate.grid import band_solver

MAX_ITERATIONS = 50
"""Most active-set iterations."""

TILT_ROUNDS = 2
"""Active-set solves: the second with the tilt of the ball contacts at the predicted slope."""

SUPPORT_STIFFNESS = 1e3
"""The three supports of the flexibility, relative to the plate's stiffness scale."""


class ContactPredictor:
    """Elastic flexibility of a plate at its punch axes, and the contact problem on it.

    Parameters
    ----------
    model : PlateModel
    """

    def __init__(self, model):
        self.model = model
        punches, grid = model.punches, model.grid
        m = punches.count
        uv = grid.to_plate(punches.xy_mm)
        modes = np.column_stack([np.ones(m), uv[:, 0], np.zeros(m) if grid.cylindrical else uv[:, 1]])
        keep = np.linalg.norm(modes, axis=0) > 0
        self.axis_modes = modes[:, keep]
        self.dof_modes = grid.rigid_modes()[:, keep]
        # the plate on three stiff supports: the pairs nearest to three spread corners
        supports = _spread(uv, self.axis_modes.shape[1])
        spring = SUPPORT_STIFFNESS * model.stiffness_scale
        rows = punches.rows[0]
        band = model.elastic_band + grid.band(spring * rows[supports, :, None] * rows[supports, None, :],
                                              punches.cell[supports])
        loads = np.zeros((grid.n_dof, m))
        np.add.at(loads, (punches.dof, np.arange(m)[:, None]), rows)
        self.shapes = band_solver(band + model.regularisation)(loads)
        self.flexibility = np.sum(rows[:, :, None] * self.shapes[punches.dof], axis=1)
        self._sign = np.concatenate([np.ones(m), -np.ones(m)])
        self._bowl = model.bowl

    def predict(self, q_ref, force_ref, frame_ref, lower_mm, upper_mm, enabled):
        """The elastic plate's equilibrium between the tips, from a reference equilibrium.

        Parameters
        ----------
        q_ref : (n_dof,) float
            Reference shape (an equilibrium with ``force_ref``, or the free plate before its
            first step with no forces; the forces always carry the plate's weight).
        force_ref : (2 m,) float
            Its contact forces (lower, then upper), N.
        frame_ref : (2,) float
            Its matrix deflections, mm.
        lower_mm, upper_mm : (m,) float
            Tips of this increment, mm.
        enabled : (m,) bool
            Pairs in use.

        Returns
        -------
        q : (n_dof,) float
            The predicted shape.
        frame_mm : (2,) float
            The predicted matrix deflections.
        pushing : (2 m,) bool
            Constraints predicted to push (the solver's first active set).
        """
        punches = self.model.punches
        m = punches.count
        f_ref = force_ref[:m] - force_ref[m:]
        w0 = punches.mid_surface_mm(q_ref) - self.flexibility @ f_ref
        balance = -self.dof_modes.T @ self.model.weight_n
        allowed = np.concatenate([enabled, enabled])
        q, frame, active = q_ref, np.asarray(frame_ref, dtype=float), None
        for _ in range(TILT_ROUNDS):
            # the tips' limits at the current slope: lower side w >= lo, upper side w <= hi
            _, wu, wv = np.sum(punches.rows * np.asarray(q)[punches.dof], axis=2)
            tilt = (punches.radius_mm + 0.5 * punches.thickness_mm) * (np.sqrt(1.0 + wu**2 + wv**2) - 1.0)
            limit = np.concatenate([lower_mm + 0.5 * punches.thickness_mm + tilt,
                                    upper_mm - 0.5 * punches.thickness_mm - tilt])
            active = self._start(w0, limit, allowed) if active is None else active
            for _ in range(MAX_ITERATIONS):
                force, a, frame = self._solve(active, w0, limit, balance)
                w = w0 + self.flexibility @ (force[:m] - force[m:]) + self.axis_modes @ a
                gap = np.concatenate([w, -w]) - self._sign * limit + self._bowl @ frame
                new = allowed & ((active & (force > 0)) | (~active & (gap < 0)))
                if np.array_equal(new, active):
                    break
                active = new
            q = q_ref + self.shapes @ (force[:m] - force[m:] - f_ref) + self.dof_modes @ a
        return q, frame, active

    def _start(self, w0, limit, allowed):
        """First active sides: where the reference shape would be beyond its limits."""
        m = len(w0)
        active = allowed & (np.concatenate([w0, -w0]) - self._sign * limit < 0)
        if active.sum() < self.axis_modes.shape[1]:
            # hardly held: the plate rests on the lower tips nearest to it (within 1 mm)
            height = np.where(allowed[:m], w0 - limit[:m], np.inf)
            active[:m] |= height <= height.min() + 1.0
        return active

    def _solve(self, active, w0, limit, balance):
        """Side forces (2 m,), rigid amplitudes (k,) and matrix deflections (2,) of the active sides.

        Unknowns: the active sides' forces, the rigid amplitudes and (with a compliant frame)
        the two deflections. Equations: each active side on its limit (moved by the bowl),
        the balance of the rigid modes, the two frame springs.
        """
        model = self.model
        c_p, c_f = model.compliance.punch_mm_per_n, model.compliance.frame_mm_per_n
        m = len(w0)
        sides = np.nonzero(active)[0]
        pair, sign = sides % m, self._sign[sides]
        h, k, nf = len(sides), self.axis_modes.shape[1], 2 if c_f > 0 else 0
        matrix = np.zeros((h + k + nf, h + k + nf))
        matrix[:h, :h] = np.outer(sign, sign) * self.flexibility[np.ix_(pair, pair)] + c_p * np.eye(h)
        matrix[:h, h:h + k] = sign[:, None] * self.axis_modes[pair]
        matrix[h:h + k, :h] = matrix[:h, h:h + k].T
        rhs = np.concatenate([sign * (limit[sides] - w0[pair]), balance, np.zeros(nf)])
        if nf:
            bowl = self._bowl[sides]
            matrix[:h, h + k:] = bowl
            matrix[h + k:, :h] = bowl.T
            matrix[h + k:, h + k:] = -np.eye(2) / c_f
        # equilibrate rows and columns: the entries span mm/N to 1/c_f
        row = 1.0 / np.maximum(np.max(np.abs(matrix), axis=1), 1e-300)
        col = 1.0 / np.maximum(np.max(np.abs(matrix * row[:, None]), axis=0), 1e-300)
        scaled = matrix * row[:, None] * col
        try:
            solution = col * np.linalg.solve(scaled, rhs * row)
        except np.linalg.LinAlgError:  # supports in a line: the least-squares answer is a fine prediction
            solution = col * np.linalg.lstsq(scaled, rhs * row, rcond=1e-12)[0]
        force = np.zeros(2 * m)
        force[sides] = solution[:h]
        return force, solution[h:h + k], solution[h + k:] if nf else np.zeros(2)


def _spread(uv, count: int) -> np.ndarray:
    """Indices of ``count`` points far apart (nearest to corners of the bounding box)."""
    lo, hi = uv.min(axis=0), uv.max(axis=0)
    corners = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])[:max(count, 1)]
    if count == 2:
        corners = np.array([[lo[0], 0.5 * (lo[1] + hi[1])], [hi[0], 0.5 * (lo[1] + hi[1])]])
    picks = [int(np.argmin(np.sum((uv - c) ** 2, axis=1))) for c in corners]
    return np.unique(picks)
