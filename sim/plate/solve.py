"""Equilibrium of the plate: loaded between the punches, and sprung back free.

**Loaded.** Unknowns: the plate's B-spline unknowns ``q`` and, with a compliant frame, the
deflections ``delta = (delta_lower, delta_upper)`` of the two matrices at the bed centre.
Equations (contact law in :mod:`mppf.sim.plate.contact`)::

    R_q     = f_int(q) - f_weight - A^T f = 0,      f = max(0, -(g(q) + B delta)) / c_p
    R_delta = delta / c_f - B^T f         = 0

``A = dg/dq``, ``B`` the bowl factors of the lower and the upper constraints. Semi-smooth
Newton: the Jacobian (the plate's consistent layer tangent, the punch springs of the
constraints that touch, and the tilt terms ``sum f d^2(-g)/dq^2``) is symmetric positive
definite; it is assembled in band storage and factorised by banded Cholesky, the two frame
unknowns are a 2 x 2 Schur complement. A line search on ``d . R(x + a d)`` (the slope of the
incremental energy along the step) damps the switching of constraints. A tiny mass term in
the Newton matrix only keeps a plate that has lost its supports solvable. Each increment
starts from the elastic contact prediction of :mod:`mppf.sim.plate.predict` (shape and
first active set).

**Unloaded.** The punches retract: the contact forces (and the weight) are removed in
``increments`` steps, Newton on ``f_int(q) = (1 - s) f_loaded``; each Newton step is
projected so that the plate keeps its mean plane (the integrals of ``w``, ``u w``, ``v w``).
Unloading is elastic unless the residual stresses reach the reverse yield stress.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.errors import MppfError
from mppf.sim.plate.grid import band_solver
from mppf.sim.plate.material import GRAVITY_MM_S2
from mppf.sim.plate.through_thickness import LayerState, layered_response

MAX_ITERATIONS = 40
"""Most Newton iterations of one equilibrium."""

FORCE_TOLERANCE = 1e-4
"""Converged when the out-of-balance force is below this share of the applied forces."""

REGULARISATION = 1e-10
"""Mass term of the Newton matrix, relative to its stiffness."""

UNLOADED_REGULARISATION = 1e-3
"""Share of the mass term kept when unloading (the rigid modes are projected out instead)."""

LINE_SEARCH_STEPS = 4
"""Most extra residual evaluations of the line search."""



class PlateSolveError(MppfError, RuntimeError):
    """The plate's equilibrium did not converge."""


@dataclass(frozen=True, eq=False)
class Equilibrium:
    """A converged state of the plate.

    Attributes
    ----------
    q : (n_dof,) float
        The plate's unknowns (B-spline coefficients of the mid-surface), mm.
    state : LayerState
        Plastic state at that shape.
    force_n : (2 m,) float
        Contact forces of the lower, then the upper constraints, N (zero when unloaded).
    frame_mm : (2,) float
        Deflection of the lower and the upper matrix at the bed centre, mm.
    iterations : int
        Newton iterations used.
    residual : float
        Final out-of-balance force relative to the applied forces.
    """

    q: np.ndarray
    state: LayerState
    force_n: np.ndarray
    frame_mm: np.ndarray
    iterations: int
    residual: float


class PlateModel:
    """One plate on one press: grid, layer law, local properties, punches and compliance.

    Parameters
    ----------
    grid : PlateGrid
    law : LayerLaw
    plate : PhysicalPlate
    punches : Punches
    compliance : Compliance
    """

    def __init__(self, grid, law, plate, punches, compliance):
        self.grid, self.law, self.plate, self.punches, self.compliance = grid, law, plate, punches, compliance
        uv = grid.gauss_uv
        self.thickness_mm = plate.thickness_at(uv)
        self.yield_factor = plate.yield_factor(uv)
        pressure_mpa = plate.steel.density_kg_mm3 * GRAVITY_MM_S2 * 1e-3 * self.thickness_mm
        self.weight_n = -grid.assemble_vector((grid.gauss_weight_mm2 * pressure_mpa)[:, None] * grid.value)
        self.all_cells = np.arange(len(grid.cell_dof))
        _, tangent0, _ = self.response(np.zeros(grid.n_dof), LayerState.virgin(len(uv), len(law.xi)))
        self.elastic_band = self.stiffness_band(tangent0)
        mass = grid.mass_band()
        self.stiffness_scale = float(np.mean(self.elastic_band[0]))
        self.regularisation = REGULARISATION * self.stiffness_scale / float(np.mean(mass[0])) * mass
        self.rigid_rows, self.rigid_modes = grid.rigid_rows(), grid.rigid_modes()
        m = punches.count
        self.bowl = np.zeros((2 * m, 2))
        self.bowl[:m, 0] = punches.bowl
        self.bowl[m:, 1] = punches.bowl
        self.cells2 = np.concatenate([punches.cell, punches.cell])
        self.newton_slots = grid.band_slots(self.all_cells, self.cells2, punches.cell)

    def response(self, q, state: LayerState, hint: LayerState | None = None):
        """Internal force (n_dof,) N, through-thickness tangent (LayeredTangent) and trial state at ``q``.

        ``hint`` is a nearby trial state (the previous Newton iterate's) that speeds up the
        return mapping.
        """
        grid = self.grid
        moment, tangent, trial = layered_response(self.law, grid.curvatures(q), state, self.thickness_mm,
                                                  self.yield_factor, hint)
        force = grid.assemble_vector(np.einsum("gai,ga->gi", grid.curvature, moment * grid.gauss_weight_mm2[:, None]))
        return force, tangent, trial

    def stiffness_blocks(self, layered_tangent) -> np.ndarray:
        """The cells' tangent stiffness matrices (e, 16, 16), N/mm, from a LayeredTangent."""
        grid = self.grid
        kb = np.matmul(layered_tangent.matrix() * grid.gauss_weight_mm2[:, None, None], grid.curvature)
        # per cell: its 4 Gauss points' (3, 16) rows stacked to (12, 16)
        rows = grid.curvature.reshape(-1, 12, 16)
        return np.matmul(rows.transpose(0, 2, 1), kb.reshape(-1, 12, 16))

    def stiffness_band(self, layered_tangent) -> np.ndarray:
        """The plate's tangent stiffness in band storage, N/mm, from a LayeredTangent."""
        return self.grid.band(self.stiffness_blocks(layered_tangent), self.all_cells)

    def contact(self, q, frame_mm, lower_mm, upper_mm, allowed, guess=None):
        """Gaps, Jacobian rows, forces and spring rates of the constraints at ``q``.

        Parameters
        ----------
        q : (n_dof,) float
        frame_mm : (2,) float
        lower_mm, upper_mm : (m,) float
        allowed : (2 m,) bool
        guess : (2 m,) bool, optional
            Constraints to treat as pushing although their gap may be open (their force is
            then extrapolated from the law, negative while open).

        Returns
        -------
        slack : (2 m,) float
            Gap after the compliance, mm.
        jac : (2 m, 16) float
            Local Jacobian rows.
        force : (2 m,) float
            Contact forces, N.
        rate : (2 m,) float
            d force / d penetration, N/mm (of the extrapolated law where guessed).
        branch : (2 m,) float
            The forces of the Newton model: ``force``, or the extrapolation where guessed.
        """
        gap, jac = self.punches.gaps(q, lower_mm, upper_mm)
        slack = gap + self.bowl @ frame_mm
        spring = 1.0 / self.compliance.punch_mm_per_n
        pushing = allowed & (slack < 0.0)
        force = np.where(pushing, -slack * spring, 0.0)
        if guess is None:
            return slack, jac, force, np.where(pushing, spring, 0.0), force
        guessed = allowed & (pushing | guess)
        return slack, jac, force, np.where(guessed, spring, 0.0), np.where(guessed, -slack * spring, 0.0)

    def keep_plane(self, dq) -> np.ndarray:
        """``dq`` (n_dof,) minus the rigid motion that changes the plate's mean plane."""
        a, *_ = np.linalg.lstsq(self.rigid_rows @ self.rigid_modes, self.rigid_rows @ dq, rcond=1e-12)
        return dq - self.rigid_modes @ a


@dataclass(frozen=True, eq=False)
class Tips:
    """The punch tips of one load increment, as the PLC read them back.

    Attributes
    ----------
    lower_mm, upper_mm : (m,) float
        Tip heights of the punch pairs over the plate, mm.
    enabled : (m,) bool
        Pairs that take part (inactive or parked punches do not touch).
    """

    lower_mm: np.ndarray
    upper_mm: np.ndarray
    enabled: np.ndarray


def solve_loaded(model: PlateModel, q, frame_mm, state: LayerState, tips: Tips, guess=None,
                 max_iterations: int = MAX_ITERATIONS) -> Equilibrium:
    """Equilibrium between the punches (tips as the PLC read them back).

    Parameters
    ----------
    model : PlateModel
    q : (n_dof,) float
        Start shape.
    frame_mm : (2,) float
        Start deflections of the matrices.
    state : LayerState
        Committed plastic state (the start of this load increment).
    tips : Tips
        The tips of the punch pairs over the plate.
    guess : (2 m,) bool, optional
        Constraints expected to push: they take part in the first Newton matrix even
        where the start shape does not touch them.
    max_iterations : int
        Newton iterations allowed.

    Returns
    -------
    Equilibrium

    Raises
    ------
    PlateSolveError
        No convergence within ``max_iterations``.
    """
    enabled = tips.enabled
    bounds = (np.where(enabled, tips.lower_mm, 0.0), np.where(enabled, tips.upper_mm, 0.0),
              np.concatenate([enabled, enabled]))
    x = _Iterate(model, np.asarray(q, dtype=float), np.asarray(frame_mm, dtype=float), state, bounds, guess)
    for iteration in range(max_iterations):
        # 1. converged: in balance
        if x.relative <= FORCE_TOLERANCE:
            return Equilibrium(x.q, x.trial, x.force, x.frame, iteration, x.relative)
        # 2. Newton direction of shape and frame deflection, then a line search along it
        dq, dframe = _newton_direction(model, x)
        x = _line_search(x, dq, dframe)
    raise PlateSolveError(f"the loaded plate did not reach equilibrium in {max_iterations} iterations "
                          f"(out-of-balance {x.relative:.2e} of the forces)",
                          hint="use more load increments or a finer grid; check the strokes for jumps")


class _Iterate:
    """The loaded plate at one iterate: response, contact, residual."""

    def __init__(self, model, q, frame, state, bounds, guess=None, hint=None):
        """``bounds``: the lower and upper tips (m,) mm, 0 where disabled, and the constraints allowed (2 m,) bool."""
        self.model, self.q, self.frame, self.state, self.bounds = model, q, frame, state, bounds
        lower, upper, allowed = bounds
        self.f_int, self.layered_tangent, self.trial = model.response(q, state, hint)
        self.slack, self.jac, self.force, self.rate, self.branch = model.contact(q, frame, lower, upper, allowed,
                                                                                  guess)
        push = model.punches.transpose_times(self.jac, self.force)
        self.residual = self.f_int - model.weight_n - push
        c_frame = model.compliance.frame_mm_per_n
        self.frame_residual = frame / c_frame - model.bowl.T @ self.force if c_frame > 0 else np.zeros(2)
        scale = np.linalg.norm(model.punches.transpose_times(self.jac, np.abs(self.force)))
        scale += np.linalg.norm(model.weight_n)
        imbalance = np.linalg.norm(self.residual) + np.linalg.norm(self.frame_residual)
        self.relative = float(imbalance / max(scale, 1e-12))

    def moved(self, dq, dframe, step: float) -> _Iterate:
        """The iterate ``step`` along the direction."""
        return _Iterate(self.model, self.q + step * dq, self.frame + step * dframe, self.state, self.bounds,
                        hint=self.trial)

    def slope(self, dq, dframe) -> float:
        """d . R: the slope of the incremental energy along the direction."""
        return float(dq @ self.residual + dframe @ self.frame_residual)


def _newton_direction(model: PlateModel, x: _Iterate):
    """Newton step (n_dof,), (2,) of the loaded equations."""
    comp, grid, punches = model.compliance, model.grid, model.punches
    rate = x.rate
    springs = rate[:, None, None] * x.jac[:, :, None] * x.jac[:, None, :]
    band = grid.band_of(model.newton_slots, model.stiffness_blocks(x.layered_tangent), springs,
                        punches.tilt_blocks(x.q, x.force)) + model.regularisation
    try:
        solve = band_solver(band)
    except np.linalg.LinAlgError:
        raise PlateSolveError("the plate's Newton matrix is not positive definite",
                              hint="use more load increments") from None
    # the Newton model's forces (guessed constraints push on the extrapolated law)
    branch = x.branch - x.force
    residual = x.residual - punches.transpose_times(x.jac, branch)
    if comp.frame_mm_per_n <= 0:
        return solve(-residual), np.zeros(2)
    frame_residual = x.frame_residual - model.bowl.T @ branch
    coupling = np.column_stack([punches.transpose_times(x.jac, rate * model.bowl[:, k]) for k in range(2)])
    frame_matrix = np.eye(2) / comp.frame_mm_per_n + model.bowl.T @ (rate[:, None] * model.bowl)
    solved = solve(np.column_stack([-residual, coupling]))
    schur = frame_matrix - coupling.T @ solved[:, 1:]
    dframe = np.linalg.solve(schur, -frame_residual - coupling.T @ solved[:, 0])
    return solved[:, 0] - solved[:, 1:] @ dframe, dframe


def _line_search(x: _Iterate, dq, dframe) -> _Iterate:
    """The iterate along the Newton direction: the full step, or where the energy's slope vanishes.

    The full step is kept if it halves the out-of-balance force or the incremental energy
    does not rise at its end (slope at most half the initial descent); otherwise regula
    falsi on the slope between 0 and 1.
    """
    slope0 = x.slope(dq, dframe)
    lo, s_lo, hi = 0.0, slope0, 1.0
    trial = x.moved(dq, dframe, hi)
    s_hi = trial.slope(dq, dframe)
    if slope0 >= 0.0 or s_hi <= 0.5 * abs(slope0) or trial.relative < 0.5 * x.relative:
        return trial
    for _ in range(LINE_SEARCH_STEPS):
        step = lo - s_lo * (hi - lo) / (s_hi - s_lo)
        step = float(np.clip(step, lo + 0.05 * (hi - lo), hi - 0.05 * (hi - lo)))
        trial = x.moved(dq, dframe, step)
        s = trial.slope(dq, dframe)
        if abs(s) <= 0.5 * abs(slope0):
            break
        if s < 0.0:
            lo, s_lo = step, s
        else:
            hi, s_hi = step, s
    return trial


def solve_unloaded(model: PlateModel, loaded: Equilibrium, increments: int = 1) -> Equilibrium:
    """Spring-back: the plate after the punches retract (free, mean plane kept).

    Parameters
    ----------
    model : PlateModel
    loaded : Equilibrium
        The loaded state.
    increments : int
        Steps in which the contact forces and the weight are removed.

    Returns
    -------
    Equilibrium
        With zero contact forces and frame deflections.

    Raises
    ------
    PlateSolveError
        No convergence within :data:`MAX_ITERATIONS` in an increment.
    """
    zeros = np.zeros(model.punches.count)
    _, jac = model.punches.gaps(loaded.q, zeros, zeros)
    load = model.punches.transpose_times(jac, loaded.force_n) + model.weight_n
    scale = max(float(np.linalg.norm(load)), 1e-9)
    q, state, total = loaded.q.copy(), loaded.state, 0
    for step in range(1, increments + 1):
        applied = (1.0 - step / increments) * load
        trial = None
        for iteration in range(MAX_ITERATIONS + 1):
            f_int, tangent, trial = model.response(q, state, trial)
            residual = f_int - applied
            relative = float(np.linalg.norm(residual) / scale)
            if iteration > 0 and relative <= FORCE_TOLERANCE:
                break
            if iteration == MAX_ITERATIONS:
                raise PlateSolveError(f"the unloaded plate did not reach equilibrium in {MAX_ITERATIONS} "
                                      f"iterations (out-of-balance {relative:.2e})",
                                      hint="use more unloading increments")
            solve = band_solver(model.stiffness_band(tangent) + UNLOADED_REGULARISATION * model.regularisation)
            q = q + model.keep_plane(solve(-residual))
        state, total = trial, total + iteration
    return Equilibrium(q, state, np.zeros_like(loaded.force_n), np.zeros(2), total, relative)
