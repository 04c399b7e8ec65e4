"""The measured correction: stroke changes from this plate's measured response, on the loading side of memory.

Hull plates are bent near their elastic-limit curvature, where the residual curvature as a
function of the loaded one is very non-linear (for an elastic-perfectly-plastic section
``r = k - 1.5 k_e (1 - k_e^2 / (3 k^2))``: secant ``r / k`` 0.15 but tangent ``1 - (k_e / k)^3``
0.70 at ``k = 1.5 k_e``). A model whose elastic stretch is slightly off predicts almost no
change for a stroke change that the plate answers fully. This correction therefore does not
ask a model how far to press; it asks the plate:

- **the response** ``G`` of the plate, in loaded-height space: the change of the measured
  deviation at the punches per change of the loaded mid heights (the strokes' mid heights, as
  the press read them back), in smooth modes of the punch grid (those of
  :class:`mppf.correct.secant.ModeGain`, plane removed) and a scalar ``g_local`` for what the
  modes do not describe. Before any secant ``G = 1``: on the loading side of plastic memory
  (pressing further in the direction already bent, beyond the last loaded shape) the residual
  change never exceeds the loaded change (springback and the press's give only take away), so
  ``G = 1`` is the most responsive plate physically possible and a step sized by it cannot
  overshoot there. After each pair of measured cycles ``G`` is updated by Broyden's rule,
  regularised by the scan's noise: ``G <- G + (v - G u) u^T / (u^T u + n s^2)`` (``u`` the
  loaded change, ``v`` the measured change, in mode coefficients; ``n`` modes, ``s`` the noise
  of a punch deviation); a secant within the noise teaches nothing. Singular values are held to
  :data:`mppf.correct.policy.RESPONSE_RANGE`.
- **the step**: ``delta_loaded = -share G^-1 e`` (``e`` the deviation at the punches, the outer
  rows balanced with the net plate's edge by :func:`mppf.correct.edge.balanced_error`), added
  to both matrices' strokes.
- **over-bent punches** (the step's curvature presses against the springback curvature, loaded
  minus measured, by more than the curvature of the scan's noise) need a reverse bend past the
  plate's elastic stretch, which the loading-side response does not describe. There the loaded
  curvature is changed further by :data:`REVERSE_STRETCH` times the springback curvature against
  it (:func:`reverse_bend`), integrated to heights and held at every punch to ``|e| / g_min``
  (``g_min`` the smallest response measured on this plate, 1 before any secant): never more
  stroke than the evidence supports.

Three forms, selectable in ``benchmarks/bench_loop.py --correction`` and not used by the loop (they lose
to the learned correction: ``benchmarks/results/2026-12-06-loop-correction-3.md``, docs/correction.md):
:func:`measured_correction` (in loaded heights, as above), :func:`curvature_correction` (point by point
in curvature, integrated to heights) and :func:`hybrid_correction` (the latter with the learned
correction's reverse bend at the over-bent punches). Each leaves the first correction to the learned one:
the first press leaves elastic gaps that only the model knows.
"""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np

from mppf.core.grid import largest_neighbour_difference
from mppf.correct.calibrate import Calibration
from mppf.correct.edge import balanced_error
from mppf.correct.learned import LearnedCorrection, learned_correction
from mppf.correct.policy import DEFAULT_NOISE_MM, RESPONSE_RANGE, outer_ring
from mppf.correct.punch_grid import PunchGrid
from mppf.correct.section import Section
from mppf.forming.material import Material
from mppf.planning.press import PressConfig

REVERSE = True
"""Over-bent punches get the reverse bend past the elastic stretch (False: only the displacement step)."""

REVERSE_STRETCH = 4.0 / 3.0
"""Elastic stretch of a reverse bend in springbacks (curvature): the plate yields again after ``2 k_e`` of
loaded change; the springback of a plate bent past its elastic limit is ``k_e`` to ``1.5 k_e``: the stretch is 4/3
to 2 springbacks. The smaller one: a reverse bend that stops short of the plate's stretch costs a cycle, one that
goes past it over-bends the other way."""


def loaded_mid(cycle) -> np.ndarray:
    """The loaded mid heights of a cycle's last step (rows, cols; NaN where inactive)."""
    return np.asarray(cycle.steps_mid_mm[-1], dtype=float)


def loading_side(grid: PunchGrid, change, springback) -> np.ndarray:
    """Active punches (m,) where a loaded change presses further in the direction already bent.

    Parameters
    ----------
    grid : PunchGrid
    change, springback : (m,) float
        The loaded change and the last loaded heights less the measured ones, at the active punches (mm).

    Returns
    -------
    (m,) bool
        The curvature of ``change`` points along the springback curvature (loaded minus unloaded).
    """
    spring = (grid.stroke_curvature @ springback).reshape(-1, 3)
    step = (grid.stroke_curvature @ change).reshape(-1, 3)
    return np.sum(step * spring, axis=1) > 0.0


class LoadedResponse:
    """The plate's measured response on the loading side: change of the deviation per change of the loaded heights.

    One ratio inside the outer ring of punches and one at it (a free edge answers differently), each a
    least-squares ratio over the loading-side punches of every secant after the first correction,
    regularised to the prior 1 by the scan's noise: ``g = (S(u v) + n s^2) / (S(u^2) + n s^2)``.

    Parameters
    ----------
    grid : PunchGrid
    ring : (m,) bool
        The outer ring among the active punches.
    noise_mm : float
        Noise of a punch deviation (mm).
    """

    def __init__(self, grid: PunchGrid, ring, noise_mm: float):
        self.grid, self.ring, self.noise_mm = grid, np.asarray(ring, dtype=bool), float(noise_mm)
        self._sums = np.zeros((2, 2))  # (inside, ring) x (S(u v), S(u^2))
        self.updates = 0
        self.smallest = 1.0

    def update(self, loaded_change, plate_change, loading) -> None:
        """One secant: loaded and measured change ((m,), mm, plane removed) and its loading-side punches ((m,))."""
        u, v = np.nan_to_num(np.asarray(loaded_change, float)), np.nan_to_num(np.asarray(plate_change, float))
        for k, part in enumerate((~self.ring, self.ring)):
            use = part & np.asarray(loading, dtype=bool)
            self._sums[k] += (np.sum(u[use] * v[use]), np.sum(u[use] ** 2))
        self.updates += 1
        self.smallest = min(self.smallest, float(self.gains.min()))

    @property
    def gains(self) -> np.ndarray:
        """(inside, ring) response ratios, held to :data:`mppf.correct.policy.RESPONSE_RANGE`."""
        prior = np.array([np.sum(~self.ring), np.sum(self.ring)]) * self.noise_mm**2
        return np.clip((self._sums[:, 0] + prior) / np.maximum(self._sums[:, 1] + prior, 1e-300), *RESPONSE_RANGE)

    def per_punch(self) -> np.ndarray:
        """The response ratio at every active punch (m,)."""
        inside, ring = self.gains
        return np.where(self.ring, ring, inside)


def learn_response(grid: PunchGrid, ring, design_mid_mm, cycles, noise_mm: float) -> LoadedResponse:
    """The plate's loading-side response from every pair of consecutive measured cycles after the first correction.

    The first correction's secant is left out: it crossed the elastic gaps of the first press (parts of a plate
    bent near its elastic limit that the first press left elastic), which no later correction meets again.
    """
    response = LoadedResponse(grid, ring, noise_mm)
    known = [c for c in cycles if c.measured and c.steps_mid_mm]
    for before, after in itertools.pairwise(known[1:]):  # not the first correction's secant
        loaded = grid.active_values(loaded_mid(before))
        springback = grid.plane_free @ (loaded - grid.active_values(np.asarray(design_mid_mm, float)
                                                                    + before.error_mm))
        u = grid.plane_free @ (grid.active_values(loaded_mid(after)) - loaded)
        v = grid.plane_free @ grid.active_values(after.error_mm - before.error_mm)
        response.update(u, v, loading_side(grid, u, springback))
    return response


def reverse_bend(grid: PunchGrid, step, springback, noise_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """The loaded curvature a reverse bend must add to cross the elastic stretch, and where (over-bent punches).

    Parameters
    ----------
    grid : PunchGrid
    step : (m,) float
        The loaded change at the active punches (mm).
    springback : (m,) float
        The last loaded heights less the measured ones at the active punches (mm).
    noise_mm : float
        Noise of a punch deviation: a step whose curvature against the bend is within the curvature of that
        noise is no reverse bend.

    Returns
    -------
    extra : (m, 3) float
        ``-REVERSE_STRETCH * springback curvature`` at the over-bent punches, 0 elsewhere (1/mm).
    reverse : (m,) bool
        The over-bent punches.
    """
    spring = (grid.stroke_curvature @ springback).reshape(-1, 3)
    change = (grid.stroke_curvature @ step).reshape(-1, 3)
    size = np.linalg.norm(spring, axis=1)
    against = -np.sum(change * spring, axis=1) / np.maximum(size, 1e-300)
    noise = noise_mm * np.sqrt(6.0) / (grid.press.pitch_x_mm * grid.press.pitch_y_mm)
    reverse = against > noise
    return np.where(reverse[:, None], -REVERSE_STRETCH * spring, 0.0), reverse


def measured_correction(press: PressConfig, design_mid_mm, thickness_mm: float, nominal: Material, cycles,
                        base_upper_mm, base_lower_mm, active, edge_mm=None, share: float = 1.0,
                        noise_mm: float = DEFAULT_NOISE_MM) -> LearnedCorrection:
    """The next strokes from this plate's measured response (see the module docstring).

    Parameters
    ----------
    press : PressConfig
    design_mid_mm : (rows, cols) float
        The design's mid-surface height at the punches (mm).
    thickness_mm : float
    nominal : Material
        The material the planner assumed (only reported).
    cycles : list of PressedCycle
        Every cycle so far, the last one measured.
    base_upper_mm, base_lower_mm : (rows, cols) float
        The strokes to correct (NaN where inactive).
    active : (rows, cols) bool
    edge_mm : (rows, cols) float, optional
        The net plate's edge beyond the outer punches (:func:`mppf.correct.edge.balanced_error`).
    share : float
        Share of the way asked for, in (0, 1] (:attr:`mppf.correct.policy.StepPlan.share`).
    noise_mm : float
        Noise of a punch deviation (mm).

    Returns
    -------
    LearnedCorrection
        The strokes, the deviation they are expected to leave, the response's singular values.
    """
    if sum(1 for c in cycles if c.measured) < 2:  # the first correction: the model knows the elastic gaps
        return learned_correction(press, design_mid_mm, thickness_mm, nominal, cycles, base_upper_mm, base_lower_mm,
                                  active, edge_mm=edge_mm, scale=np.full(np.shape(active), share))
    grid = PunchGrid(press, active)
    ring = outer_ring(active).ravel()[grid.index]
    response = learn_response(grid, ring, design_mid_mm, cycles, noise_mm)
    error = grid.plane_free @ grid.active_values(balanced_error(cycles[-1].error_mm, edge_mm))
    step = -share * error / response.per_punch()
    # over-bent punches: the step presses against the bend, a reverse bend must cross the elastic stretch
    loaded = grid.active_values(loaded_mid(cycles[-1]))
    unloaded = grid.active_values(np.asarray(design_mid_mm, float) + cycles[-1].error_mm)
    springback = grid.plane_free @ (loaded - unloaded)
    reverse = ~loading_side(grid, step, springback)
    if REVERSE:
        extra, _ = reverse_bend(grid, step, springback, 0.0)
        limit = np.abs(error) / response.smallest  # never more than the smallest measured response supports
        step = step + np.clip(grid.heights_matrix @ extra.ravel(), -limit, limit)
    section = Section(thickness_mm, nominal.youngs_modulus_mpa, nominal.poisson, nominal.yield_stress_mpa)
    return _strokes(press, grid, base_upper_mm, base_lower_mm, grid.to_field(step), error, response, section,
                    reverse, share)


def _curvature(grid: PunchGrid, heights) -> np.ndarray:
    """Curvature (m, 3) of heights (m,) at the active punches."""
    return (grid.stroke_curvature @ heights).reshape(-1, 3)


def learn_curvature_response(grid: PunchGrid, ring, design_mid_mm, cycles, noise_per_mm: float) -> LoadedResponse:
    """The loading-side response point by point in curvature, from every secant after the first correction."""
    response = LoadedResponse(grid, ring, noise_per_mm)
    design = np.asarray(design_mid_mm, float)
    known = [c for c in cycles if c.measured and c.steps_mid_mm]
    for before, after in itertools.pairwise(known[1:]):  # not the first correction's secant
        loaded = grid.curvature(loaded_mid(before))
        spring = loaded - grid.curvature(design + before.error_mm)
        u = grid.curvature(loaded_mid(after)) - loaded
        v = grid.curvature(design + after.error_mm) - grid.curvature(design + before.error_mm)
        response.update(u, v, np.sum(u * spring, axis=1) > 0.0)
    return response


def curvature_correction(press: PressConfig, design_mid_mm, thickness_mm: float, nominal: Material, cycles,
                         base_upper_mm, base_lower_mm, active, edge_mm=None, share: float = 1.0,
                         noise_mm: float = DEFAULT_NOISE_MM, variant: str = "") -> LearnedCorrection:
    """:func:`measured_correction` point by point in curvature instead of heights (same parameters and result).

    The loaded curvature change at every punch is the wanted residual curvature change over the measured
    loading-side response (``g``, 1 before any secant); where it presses against the bend the elastic stretch
    of a reverse bend is added, :data:`REVERSE_STRETCH` springbacks, held to ``|wanted| / g_min``; the field is
    integrated to heights (:attr:`mppf.correct.punch_grid.PunchGrid.heights_matrix`). ``variant``: of the first
    correction (the learned one), :func:`mppf.correct.learned.learned_correction`.
    """
    if sum(1 for c in cycles if c.measured) < 2:  # the first correction: the model knows the elastic gaps
        return learned_correction(press, design_mid_mm, thickness_mm, nominal, cycles, base_upper_mm, base_lower_mm,
                                  active, edge_mm=edge_mm, scale=np.full(np.shape(active), share), variant=variant)
    grid = PunchGrid(press, active)
    ring = outer_ring(active).ravel()[grid.index]
    noise_per_mm = noise_mm * np.sqrt(6.0) / (press.pitch_x_mm * press.pitch_y_mm)
    response = learn_curvature_response(grid, ring, design_mid_mm, cycles, noise_per_mm)
    error = grid.plane_free @ grid.active_values(balanced_error(cycles[-1].error_mm, edge_mm))
    want = -share * _curvature(grid, error)
    design = np.asarray(design_mid_mm, float)
    spring = grid.curvature(loaded_mid(cycles[-1])) - grid.curvature(design + cycles[-1].error_mm)
    reverse = np.sum(want * spring, axis=1) < 0.0
    step = want / response.per_punch()[:, None]
    extra = np.where(reverse[:, None], -REVERSE_STRETCH * spring, 0.0)
    size, limit = np.linalg.norm(extra, axis=1), np.linalg.norm(want, axis=1) / response.smallest
    extra = extra * np.minimum(1.0, limit / np.maximum(size, 1e-300))[:, None]
    change = grid.heights_matrix @ (step + extra).ravel()
    section = Section(thickness_mm, nominal.youngs_modulus_mpa, nominal.poisson, nominal.yield_stress_mpa)
    return _strokes(press, grid, base_upper_mm, base_lower_mm, grid.to_field(change), error, response, section,
                    reverse, share)


def hybrid_correction(press: PressConfig, design_mid_mm, thickness_mm: float, nominal: Material, cycles,
                      base_upper_mm, base_lower_mm, active, edge_mm=None, share: float = 1.0,
                      noise_mm: float = DEFAULT_NOISE_MM, variant: str = "") -> LearnedCorrection:
    """:func:`curvature_correction` on the loading side, the learned correction's reverse bend where over-bent.

    Point by point in curvature: where the wanted change presses further into the bend, the loaded change is the
    wanted one over the measured loading-side response; where it presses against the bend (over-bent), the loaded
    curvature change of the learned correction (its model knows the elastic stretch a reverse bend must cross),
    held to ``2 k_e + |wanted| / g_min`` (``k_e`` the calibrated model's elastic-limit curvature, ``g_min`` the
    smallest response measured on this plate). The field is integrated to heights. Same parameters and result as
    :func:`measured_correction`; ``variant`` as in :func:`curvature_correction`.
    """
    learned = learned_correction(press, design_mid_mm, thickness_mm, nominal, cycles, base_upper_mm, base_lower_mm,
                                 active, edge_mm=edge_mm, scale=np.full(np.shape(active), share), variant=variant)
    if sum(1 for c in cycles if c.measured) < 2:  # the first correction: the model knows the elastic gaps
        return learned
    grid = PunchGrid(press, active)
    ring = outer_ring(active).ravel()[grid.index]
    noise_per_mm = noise_mm * np.sqrt(6.0) / (press.pitch_x_mm * press.pitch_y_mm)
    response = learn_curvature_response(grid, ring, design_mid_mm, cycles, noise_per_mm)
    error = grid.plane_free @ grid.active_values(balanced_error(cycles[-1].error_mm, edge_mm))
    want = -share * _curvature(grid, error)
    design = np.asarray(design_mid_mm, float)
    spring = grid.curvature(loaded_mid(cycles[-1])) - grid.curvature(design + cycles[-1].error_mm)
    reverse = np.sum(want * spring, axis=1) < 0.0
    model = _curvature(grid, grid.active_values(learned.change_mm))
    limit = 2.0 * learned.calibration.section.elastic_limit_per_mm + np.linalg.norm(want, axis=1) / response.smallest
    size = np.linalg.norm(model, axis=1)
    model = model * np.minimum(1.0, limit / np.maximum(size, 1e-300))[:, None]
    step = np.where(reverse[:, None], model, want / response.per_punch()[:, None])
    change = grid.to_field(grid.heights_matrix @ step.ravel())
    out = _strokes(press, grid, base_upper_mm, base_lower_mm, change, error, response, learned.calibration.section,
                   reverse, share)
    predicted = np.where(grid.to_field(reverse.astype(float)) == 1.0, learned.predicted_mm, out.predicted_mm)
    return replace(out, predicted_mm=predicted, calibration=learned.calibration,
                   notes=[*learned.notes[:1], *out.notes[:1],
                          (f"{int(reverse.sum())} over-bent punch(es): the learned reverse bend, held to 2 k_e + "
                           f"the wanted change / {response.smallest:.2f}")])


def _strokes(press, grid, base_upper, base_lower, change, error, response, section, reverse, share):
    """The strokes within the stroke limits, their steps and the deviation expected (loading side only)."""
    act = grid.active
    change = np.where(act, change, 0.0)
    upper = np.where(act, np.asarray(base_upper, dtype=float) + change, np.nan)
    lower = np.where(act, np.asarray(base_lower, dtype=float) + change, np.nan)
    clipped = act & ((upper > press.upper.max_mm) | (upper < press.upper.min_mm) | (lower > press.lower.max_mm)
                     | (lower < press.lower.min_mm))
    shift = np.clip(lower, press.lower.min_mm, press.lower.max_mm) - lower
    shift = np.where(act, shift + np.clip(upper + shift, press.upper.min_mm, press.upper.max_mm) - (upper + shift), 0.0)
    upper, lower, change = upper + shift, lower + shift, np.where(act, change + shift, 0.0)
    n_steps = max(1, int(np.ceil(largest_neighbour_difference(change, act) / press.max_neighbour_diff_mm - 1e-9)))
    made = response.per_punch() * (grid.plane_free @ grid.active_values(np.where(act, shift, 0.0)))
    predicted = grid.to_field(np.where(reverse, error, (1.0 - share) * error + made))
    notes = [(f"measured response on the loading side: {response.gains[0]:.2f} inside the outer punches, "
              f"{response.gains[1]:.2f} at them ({response.updates} secant(s)); {share:.0%} of the way"),
             (f"{int(reverse.sum())} punch(es) over-bent: reverse bend past the elastic stretch, at most "
             f"{REVERSE_STRETCH:.2f} x its springback curvature, at most the error / {response.smallest:.2f}")]
    calibration = Calibration(section, float("nan"))
    return LearnedCorrection(upper, lower, n_steps, change, predicted, calibration, response.gains,
                             np.zeros(grid.shape, dtype=bool), clipped, notes)
