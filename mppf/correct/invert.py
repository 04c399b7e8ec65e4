"""The loaded curvature that gives a wanted unloaded curvature, point by point, through the model's bending law.

The bending law's press map ``F(k) = k - D^-1 M(k | state)`` is monotone (in the metric of the
bending stiffness D: the elastic-plastic stiffness never exceeds the elastic one) but flat
wherever a change stays elastic: pressing less than before, a curvature added across a
yielding bend, the first part of a reverse bend. :func:`invert` therefore

1. searches along the ray from the last loaded curvature in the direction of the wanted
   change (bisection on the monotone share of the wanted change reached), so an elastic
   stretch is crossed instead of stalling a Newton step on it, and
2. polishes the point in all three components (damped Gauss-Newton on finite-difference
   Jacobians), which takes the coupling of the curvatures into account.

The search is held to a trust region: a loaded change of at most ``reach_per_mm`` per
point; points that cannot reach their target within it are reported.
"""

from __future__ import annotations

import numpy as np

from mppf.correct.through_thickness import BendingLaw, BendingState

BISECTIONS = 40
"""Bisection steps of the ray search."""

POLISH_STEPS = 6
"""Gauss-Newton steps of the polish."""

FD_STEP_PER_MM = 1e-7
"""Finite-difference step of the Jacobians (1/mm)."""


def stiffness(law: BendingLaw) -> np.ndarray:
    """The plate's elastic bending stiffness D (3, 3), N mm, in Voigt curvature (engineering twist)."""
    e_mod, nu, t = law.youngs_modulus_mpa, law.poisson, law.thickness_mm
    c = e_mod / (1 - nu * nu) * np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, 0.5 * (1 - nu)]])
    return t**3 / 12.0 * c


def invert(law: BendingLaw, state: BendingState, loaded, unloaded, target, reach_per_mm: float):
    """Loaded curvatures (n, 3) whose release gives ``target`` (n, 3), from the points' state.

    Parameters
    ----------
    law : BendingLaw
    state : BendingState
        The points' plastic state (after their last press).
    loaded, unloaded : (n, 3) float
        Their last loaded curvature and the unloaded one it gave (1/mm).
    target : (n, 3) float
        The wanted unloaded curvature.
    reach_per_mm : float
        Largest change of the loaded curvature per point (trust region, 1/mm).

    Returns
    -------
    kappa : (n, 3) float
        The new loaded curvatures.
    reached : (n,) bool
        Points whose target lies within the trust region.
    """
    loaded, unloaded, target = (np.asarray(a, dtype=float) for a in (loaded, unloaded, target))
    d_mat = stiffness(law)
    want = target - unloaded
    norm_d = np.einsum("ni,ij,nj->n", want, d_mat, want)
    still = norm_d <= 1e-30 * np.max(norm_d, initial=1.0)

    def share(s):
        """Share of the wanted change reached at loaded + s want (monotone in s)."""
        kappa_f, _ = law.press(loaded + s[:, None] * want, state)
        return np.einsum("ni,ij,nj->n", kappa_f - unloaded, d_mat, want) / np.where(still, 1.0, norm_d)

    size = np.linalg.norm(want, axis=1)
    s_max = np.where(still, 0.0, reach_per_mm / np.maximum(size, 1e-300))
    reached = still | (share(s_max) >= 1.0)
    lo, hi = np.zeros(len(want)), s_max.copy()
    for _ in range(BISECTIONS):
        mid = 0.5 * (lo + hi)
        up = share(mid) >= 1.0
        hi, lo = np.where(up, mid, hi), np.where(up, lo, mid)
    kappa = loaded + np.where(reached, hi, s_max)[:, None] * want
    kappa = _polish(law, state, kappa, target, loaded, reach_per_mm, still)
    return kappa, reached


def _polish(law, state, kappa, target, loaded, reach_per_mm, still):
    """Damped Gauss-Newton on all three components, kept in the trust region; only improving steps taken."""
    for _ in range(POLISH_STEPS):
        kappa_f, _ = law.press(kappa, state)
        residual = target - kappa_f
        jac = np.empty((len(kappa), 3, 3))
        for c in range(3):
            moved = kappa.copy()
            moved[:, c] += FD_STEP_PER_MM
            jac[:, :, c] = (law.press(moved, state)[0] - kappa_f) / FD_STEP_PER_MM
        jtj = np.einsum("nki,nkj->nij", jac, jac)
        damping = 1e-3 * np.trace(jtj, axis1=1, axis2=2) / 3.0 + 1e-12
        step = np.linalg.solve(jtj + damping[:, None, None] * np.eye(3),
                               np.einsum("nki,nk->ni", jac, residual)[..., None])
        trial = kappa + step[..., 0]
        change = trial - loaded
        size = np.linalg.norm(change, axis=1)
        held = loaded + change * (reach_per_mm / np.maximum(size, 1e-300))[:, None]
        trial = np.where((size > reach_per_mm)[:, None], held, trial)
        better = np.linalg.norm(target - law.press(trial, state)[0], axis=1) < np.linalg.norm(residual, axis=1)
        kappa = np.where((better & ~still)[:, None], trial, kappa)
    return kappa
