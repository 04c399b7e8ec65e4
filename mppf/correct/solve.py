"""The stroke change that makes the model plate change as wanted: a damped Gauss-Newton on the strokes.

The model's change for a stroke change ``dh`` at the active punches is

    made(dh) = H (F(C (h + dh) | state) - F(C h0 | state)),

``C`` the loaded curvature of the strokes, ``F`` the bending law's press map at every punch
from its plastic state (:meth:`mppf.correct.through_thickness.BendingLaw.press`), ``H`` the heights of a
curvature field (:class:`mppf.correct.punch_grid.PunchGrid`). :func:`solve_change` minimises
``|made(dh) - request|^2 + (alpha |C dh|)^2`` by Levenberg-Marquardt with the Jacobian
``H G C`` (``G`` the bending law's tangent at every punch, by finite differences). The map is
flat where a change stays elastic, so a Newton step from there can stall short of a
reverse bend or of a curvature added across a bend; the search therefore also starts
from the point-by-point inversion (:func:`mppf.correct.invert.invert`, which crosses the
elastic stretches), and the better end is kept.
"""

from __future__ import annotations

import numpy as np

from mppf.correct.invert import invert
from mppf.correct.punch_grid import PunchGrid
from mppf.correct.through_thickness import BendingLaw, BendingState

VIRTUAL_CYCLES = 4
"""Most virtual cycles on the model."""

POLISH_STEPS = 5
"""Levenberg-Marquardt steps on the strokes when the virtual cycles stall."""

LINE_SHARES = (1.0, 0.5, 0.25)
"""Shares of a virtual cycle's step tried, longest first."""

STALLED = 0.5
"""The virtual cycles stalled when they leave more than this share of the request (RMS)."""

FD_STEP_PER_MM = 2e-6
"""Central-difference step of the bending law's tangent (1/mm): the map has kinks where a point starts or
stops yielding, so its tangent is taken as the mean slope over a small change."""

SMOOTHING = 0.05
"""Weight ``alpha`` (mm per 1/mm of curvature, scaled by the pitch squared) of the curvature of the change."""


def solve_change(grid: PunchGrid, law: BendingLaw, state: BendingState, unloaded, base_mid_mm, request_mm,
                 reach_per_mm: float, largest_mm: float):
    """Stroke change (rows, cols) that makes the model change by ``request_mm`` (rows, cols).

    Parameters
    ----------
    grid : PunchGrid
    law : BendingLaw
    state : BendingState
        The model plate's state now (after its last press).
    unloaded : (n, 3) float
        Its unloaded curvature now.
    base_mid_mm : (rows, cols) float
        The mid heights of the strokes the change is added to.
    request_mm : (rows, cols) float
        The wanted change of the model plate at the active punches (plane removed).
    reach_per_mm : float
        Trust region of the point-by-point inversion (loaded curvature change per punch).
    largest_mm : float
        Trust region of the stroke change: no punch moves by more.

    Returns
    -------
    change_mm : (rows, cols) float
        0 where inactive.
    misfit_mm : float
        RMS of what the model still misses of the request.
    unreached : (rows, cols) bool
        Punches whose point-by-point target lay beyond the trust region.
    """
    base = grid.active_values(base_mid_mm)
    request = grid.active_values(request_mm)
    model = _Model(grid, law, state, unloaded, base)
    dh, unreached = np.zeros_like(base), np.zeros(len(base), dtype=bool)
    best = (_misfit(model, request, dh), dh, unreached)
    for _ in range(VIRTUAL_CYCLES):
        # press the model plate with the strokes so far: what is still missing
        kappa = model.kappa(best[1])
        pressed, _ = model.press(kappa)
        remaining = request - np.einsum("ipc,pc->i", model.h3, pressed - model.unloaded)
        # the loaded curvature that gives the rest, point by point (held to the trust region), as strokes
        target = pressed + grid.curvature(grid.to_field(remaining))
        new, reached = invert(law, state, kappa, pressed, target, reach_per_mm)
        step = grid.heights_matrix @ (new - kappa).ravel()
        # the longest share of that step that helps (a step that integrates badly overshoots somewhere)
        trial = next(((m, d) for m, d in ((_misfit(model, request, d), d) for d in
                                          (_within(best[1] + share * step, largest_mm) for share in LINE_SHARES))
                      if m < best[0]), None)
        if trial is None:
            break
        best = (trial[0], trial[1], ~reached)
    # stalled (a change the point-by-point inversion cannot integrate): Levenberg-Marquardt on the strokes
    if best[0] > STALLED * float(np.sqrt(np.mean(request**2))):
        best = _polish(model, request, best, largest_mm)
    change = np.zeros(grid.shape)
    change.ravel()[grid.index] = best[1]
    return change, best[0], grid.to_field(best[2].astype(float)) == 1.0


class _Model:
    """The model plate's change at the active punches for a stroke change, and its Jacobian."""

    def __init__(self, grid, law, state, unloaded, base):
        self.grid, self.law = grid, law
        self.state = state
        self.unloaded = np.asarray(unloaded, dtype=float).reshape(-1, 3)
        self.base = base
        m = len(grid.index)
        self.h3 = grid.heights_matrix.reshape(m, m, 3)

    def kappa(self, dh) -> np.ndarray:
        return (self.grid.stroke_curvature @ (self.base + dh)).reshape(-1, 3)

    def press(self, kappa):
        return self.law.press(kappa, self.state)

    def made(self, dh) -> np.ndarray:
        kappa_f, _ = self.press(self.kappa(dh))
        return np.einsum("ipc,pc->i", self.h3, kappa_f - self.unloaded)

    def jacobian(self, dh) -> np.ndarray:
        kappa = self.kappa(dh)
        kappa_f, _ = self.press(kappa)
        tangent = np.empty((len(kappa), 3, 3))
        for c in range(3):
            up, down = kappa.copy(), kappa.copy()
            up[:, c] += FD_STEP_PER_MM
            down[:, c] -= FD_STEP_PER_MM
            tangent[:, :, c] = (self.press(up)[0] - self.press(down)[0]) / (2.0 * FD_STEP_PER_MM)
        hg = np.einsum("ipc,pcd->ipd", self.h3, tangent).reshape(len(self.base), -1)
        return hg @ self.grid.stroke_curvature


def _misfit(model: _Model, request, dh) -> float:
    """RMS of what the model plate, pressed with the stroke change ``dh``, misses of the request."""
    return float(np.sqrt(np.mean((request - model.made(dh)) ** 2)))


def _polish(model: _Model, request, best, largest_mm: float):
    """Levenberg-Marquardt steps from the best point so far; only improving steps are taken."""
    misfit, dh, unreached = best
    smooth = model.grid.stroke_curvature * SMOOTHING * model.grid.press.pitch_x_mm**2
    mu = 1e-3
    for _ in range(POLISH_STEPS):
        residual = request - model.made(dh)
        jac = model.jacobian(dh)
        jtj = jac.T @ jac
        scale = np.trace(jtj) / max(len(dh), 1)
        lhs = jtj + smooth.T @ smooth + mu * scale * np.eye(len(dh))
        trial = _within(dh + np.linalg.solve(lhs, jac.T @ residual - smooth.T @ (smooth @ dh)), largest_mm)
        trial_misfit = float(np.sqrt(np.mean((request - model.made(trial)) ** 2)))
        if trial_misfit < misfit:
            misfit, dh, mu = trial_misfit, trial, mu * 0.3
        else:
            mu *= 10.0
    return misfit, dh, unreached


def _within(dh, largest_mm: float) -> np.ndarray:
    """``dh`` scaled down so that no punch moves by more than ``largest_mm``."""
    worst = float(np.max(np.abs(dh), initial=0.0))
    return dh * (largest_mm / worst) if worst > largest_mm else dh
