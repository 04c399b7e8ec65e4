"""The measured correction (mppf.correct.measured): the loading side of plastic memory, the plate's measured
response in loaded heights, and the step it sizes, against a plate the correction does not know.

The "true" plate is the correction's own section law with another yield stress and hardening (fast: no plate
solve); the steel and FE plates are exercised by benchmarks/bench_loop.py (--correction measured).
"""

from __future__ import annotations

import numpy as np
import pytest

from mppf.correct.learned import steps_towards
from mppf.correct.measured import (
    LoadedResponse,
    curvature_correction,
    hybrid_correction,
    loading_side,
    measured_correction,
    reverse_bend,
)
from mppf.correct.memory import PressedCycle, loaded_curvatures, replay
from mppf.correct.policy import outer_ring
from mppf.correct.punch_grid import PunchGrid
from mppf.correct.section import Section
from mppf.forming.material import Material
from mppf.planning.press import example_press_path, load_press

T = 20.0
NOMINAL = Material()
TRUE = Section(T, NOMINAL.youngs_modulus_mpa, NOMINAL.poisson, 275.0, 2500.0)


@pytest.fixture(scope="module")
def setup():
    press = load_press(example_press_path())
    active = np.zeros(press.shape, dtype=bool)
    active[3:11, 5:17] = True
    x, y = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    cx, cy = x[active].mean(), y[active].mean()
    design = (x - cx) ** 2 / (2 * 5000.0) + (y - cy) ** 2 / (2 * 9000.0)  # a doubly curved bowl
    return press, active, np.where(active, design, np.nan), PunchGrid(press, active)


def test_a_change_along_the_springback_is_on_the_loading_side(setup):
    _, _, design, grid = setup
    shape = grid.plane_free @ grid.active_values(design)
    springback = 0.4 * shape  # loaded deeper than the plate sprang back to
    assert loading_side(grid, 0.1 * shape, springback).all()  # more of the same bend
    assert not loading_side(grid, -0.1 * shape, springback).any()  # against it: a reverse bend


def test_the_response_is_one_before_any_secant_and_the_measured_ratio_after(setup):
    _, _, design, grid = setup
    ring = outer_ring(grid.active).ravel()[grid.index]
    response = LoadedResponse(grid, ring, noise_mm=0.3)
    np.testing.assert_array_equal(response.per_punch(), 1.0)  # the most responsive plate physically possible
    u = grid.plane_free @ grid.active_values(design)  # a large loaded change (tens of mm)
    response.update(u, 0.5 * u, np.ones(len(u), dtype=bool))
    assert response.gains == pytest.approx([0.5, 0.5], abs=0.01)
    quiet = LoadedResponse(grid, ring, noise_mm=0.3)
    quiet.update(1e-3 * u, 0.0 * u, np.ones(len(u), dtype=bool))  # a change within the noise teaches nothing
    assert quiet.gains == pytest.approx([1.0, 1.0], abs=0.02)


def test_a_reverse_bend_is_asked_only_against_the_bend(setup):
    _, _, design, grid = setup
    shape = grid.plane_free @ grid.active_values(design)
    extra, reverse = reverse_bend(grid, -0.1 * shape, 0.4 * shape, noise_mm=0.0)
    assert reverse.all()
    assert np.all(np.sum(extra * (grid.stroke_curvature @ shape).reshape(-1, 3), axis=1) < 0.0)
    extra, reverse = reverse_bend(grid, 0.1 * shape, 0.4 * shape, noise_mm=0.0)
    assert not reverse.any() and not extra.any()


def _measure(grid, design, cycles):
    unloaded = replay(TRUE, loaded_curvatures(grid, cycles), cycles).unloaded[-1]
    return grid.heights(unloaded) - grid.flat(design)


def test_an_under_bent_plate_comes_near_the_design(setup):
    press, active, design, grid = setup
    mid = np.where(active, 1.5 * design, np.nan)  # short of the springback of the harder true plate
    steps, cycles, rms = [(mid + T / 2, mid - T / 2)], [], []
    for n in range(4):
        mids = [0.5 * (u + lo) for u, lo in steps]
        error = _measure(grid, design, cycles + [PressedCycle(mids, None)])
        cycles.append(PressedCycle(mids, error))
        rms.append(float(np.sqrt(np.mean(error[active] ** 2))))
        upper, lower = steps[-1]
        step = measured_correction(press, design, T, NOMINAL, cycles, upper, lower, active)
        steps = [(s.upper_mm, s.lower_mm) for s in steps_towards(press, (upper, lower), step, active)]
    assert rms[0] > 3.0
    assert rms[2] < rms[1] < 0.5 * rms[0]  # the learned first correction, then the loading-side step
    assert rms[-1] < 0.2 * rms[0]  # (a mixed-sign residual can come back worse: docs/correction.md)


def test_point_by_point_in_curvature_the_loading_side_step_never_overshoots(setup):
    press, active, design, grid = setup
    mid = np.where(active, 1.5 * design, np.nan)
    steps, cycles, rms = [(mid + T / 2, mid - T / 2)], [], []
    for n in range(4):
        mids = [0.5 * (u + lo) for u, lo in steps]
        error = _measure(grid, design, cycles + [PressedCycle(mids, None)])
        cycles.append(PressedCycle(mids, error))
        rms.append(float(np.sqrt(np.mean(error[active] ** 2))))
        upper, lower = steps[-1]
        step = curvature_correction(press, design, T, NOMINAL, cycles, upper, lower, active)
        steps = [(s.upper_mm, s.lower_mm) for s in steps_towards(press, (upper, lower), step, active)]
    assert rms[1] < 0.5 * rms[0]
    assert rms[-1] < 0.1 * rms[0]
    assert all(b <= 1.1 * min(rms[: k + 1]) for k, b in enumerate(rms[1:]))


def test_an_over_bent_plate_is_reverse_bent_by_the_hybrid_where_the_evidence_bound_alone_stalls(setup):
    press, active, design, grid = setup
    mid = np.where(active, 3.0 * design, np.nan)  # pressed far too deep: over-bent everywhere
    ends = {}
    for correct in (curvature_correction, hybrid_correction):
        steps, cycles, rms = [(mid + T / 2, mid - T / 2)], [], []
        for n in range(5):
            mids = [0.5 * (u + lo) for u, lo in steps]
            error = _measure(grid, design, cycles + [PressedCycle(mids, None)])
            cycles.append(PressedCycle(mids, error))
            rms.append(float(np.sqrt(np.mean(error[active] ** 2))))
            upper, lower = steps[-1]
            step = correct(press, design, T, NOMINAL, cycles, upper, lower, active)
            steps = [(s.upper_mm, s.lower_mm) for s in steps_towards(press, (upper, lower), step, active)]
        ends[correct.__name__] = rms
    stalled, hybrid = ends["curvature_correction"], ends["hybrid_correction"]
    assert stalled[-1] > 0.8 * stalled[1]  # the reverse bend held to the evidence does not cross the stretch
    assert hybrid[-1] < 0.6 * hybrid[1] and hybrid[-1] < 0.15 * hybrid[0]
