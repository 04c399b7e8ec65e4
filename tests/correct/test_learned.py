"""The learned correction against a plate it does not know: another yield stress and hardening, plastic
memory from cycle to cycle, an interrupted cycle; and the next cycle's steps within the dimpling limit.

The "true" plate here is the correction's own bending law with parameters the correction is not
given (fast: no plate solve); the full steel plate is exercised by benchmarks/bench_loop.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.grid import largest_neighbour_difference
from mppf.correct.inputs import CorrectedPlate
from mppf.correct.learned import learned_correction, steps_towards
from mppf.correct.memory import PressedCycle, loaded_curvatures, replay
from mppf.correct.punch_grid import PunchGrid
from mppf.correct.through_thickness import BendingLaw
from mppf.model.material import Material
from mppf.model.press import example_press_path, load_press

T = 20.0
NOMINAL = Material()  # 235 MPa, what the correction is told
TRUE = BendingLaw(T, NOMINAL.youngs_modulus_mpa, NOMINAL.poisson, 275.0, 2500.0)  # what the plate is


def bowl():
    """(press, active, design mid heights (NaN off the plate), grid): a doubly curved bowl on the example press."""
    press = load_press(example_press_path())
    active = np.zeros(press.shape, dtype=bool)
    active[3:11, 5:17] = True
    x, y = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    cx, cy = x[active].mean(), y[active].mean()
    design = (x - cx) ** 2 / (2 * 5000.0) + (y - cy) ** 2 / (2 * 9000.0)  # a doubly curved bowl, mid-surface
    return press, active, np.where(active, design, np.nan), PunchGrid(press, active)


@pytest.fixture(scope="module")
def setup():
    return bowl()


def _measure(grid, design, cycles):
    """The true plate pressed through every cycle so far: its deviation at the punches (plane removed)."""
    unloaded = replay(TRUE, loaded_curvatures(grid, cycles), cycles).unloaded[-1]
    return grid.heights(unloaded) - grid.flat(design)


def _rms(error, active):
    return float(np.sqrt(np.mean(error[active] ** 2)))


def _first_cycle(design, active):
    mid = np.where(active, 1.5 * design, np.nan)  # over-pressed by a guessed springback factor
    return [(mid + T / 2, mid - T / 2)]


def _run(press, active, design, grid, first_steps, cycles_n=4, interrupt=None):
    """Press, measure, correct; ``interrupt=(cycle, share)`` stops that cycle's last step on its way."""
    steps, cycles, rms, predicted = first_steps, [], [], []
    for n in range(1, cycles_n + 1):
        mids = [0.5 * (u + lo) for u, lo in steps]
        stopped = interrupt is not None and interrupt[0] == n
        cycle = PressedCycle(mids, None, interrupted=stopped, share=interrupt[1] if stopped else None)
        error = _measure(grid, design, cycles + [cycle])
        cycles.append(PressedCycle(mids, error, interrupted=stopped))  # the correction is not told the share
        rms.append(_rms(error, active))
        if n == cycles_n:
            break
        upper, lower = steps[-1] if not stopped else steps[-1]
        learned = learned_correction(CorrectedPlate(press, design, T, NOMINAL, active), cycles, upper, lower)
        predicted.append(learned.predicted_rms_mm)
        steps = [(s.upper_mm, s.lower_mm) for s in steps_towards(press, (upper, lower), learned, active)]
    return rms, predicted


def test_the_correction_learns_a_plate_it_does_not_know(setup):
    press, active, design, grid = setup
    rms, predicted = _run(press, active, design, grid, _first_cycle(design, active))
    assert rms[0] > 3.0  # the plate is not what the correction was told
    assert rms[1] < 0.4 * rms[0]  # the first correction takes most of it off
    assert rms[-1] < 0.5 and rms[-1] < 0.1 * rms[0]
    assert all(b <= a + 0.05 for a, b in zip(rms, rms[1:]))  # never worse: one-sided, in a trust region
    assert predicted[0] < 0.5 * rms[0]


def test_an_over_bent_plate_is_reverse_bent(setup):
    press, active, design, grid = setup
    mid = np.where(active, 3.0 * design, np.nan)  # pressed far too deep: over-bent everywhere
    rms, _ = _run(press, active, design, grid, [(mid + T / 2, mid - T / 2)], cycles_n=4)
    assert rms[0] > 5.0
    assert rms[-1] < 0.3 * rms[0]


def test_an_interrupted_cycle_feeds_the_next_correction(setup):
    press, active, design, grid = setup
    first = _first_cycle(design, active)
    rms, _ = _run(press, active, design, grid, first, cycles_n=4, interrupt=(1, 0.5))
    assert rms[0] > 5.0  # stopped half way: far from the design
    assert rms[-1] < 0.1 * rms[0] and rms[-1] < 1.0


def test_the_next_steps_keep_the_dimpling_limit_and_end_on_the_strokes(setup):
    press, active, design, grid = setup
    (upper, lower), = _first_cycle(design, active)
    error = _measure(grid, design, [PressedCycle([0.5 * (upper + lower)], None)])
    learned = learned_correction(CorrectedPlate(press, design, T, NOMINAL, active),
                                 [PressedCycle([0.5 * (upper + lower)], error)], upper, lower)
    flat = (np.where(active, T, np.nan), np.where(active, 0.0, np.nan))
    steps = steps_towards(press, flat, learned, active)
    assert len(steps) >= 2  # from the flat plate the travel needs several steps
    np.testing.assert_allclose(steps[-1].upper_mm[active], learned.upper_mm[active])
    np.testing.assert_allclose(steps[-1].lower_mm[active], learned.lower_mm[active])
    before = np.where(active, flat[1], 0.0)
    for s in steps:
        lower_now = np.where(active, s.lower_mm, 0.0)
        assert largest_neighbour_difference(lower_now - before, active) <= press.max_neighbour_diff_mm + 1e-6
        before = lower_now
    assert any("calibrated" in note for note in learned.notes)


