"""The calibration of the model plate: the material from the first shape, the changes held to what it supports.

The "true" plate is the correction's own bending law with a yield stress and hardening the
calibration is not given (fast: no plate solve). A plate that answers a second press three
times (or a third) as much as its material says (the benchmark's ``response:3``, ``response:0.3``)
must not be taken for a much softer (harder) steel: that mismatch is left to the learned response.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_learned import NOMINAL, TRUE, T, bowl

from mppf.correct.calibrate import calibrate
from mppf.correct.memory import PressedCycle, loaded_curvatures, replay
from mppf.correct.through_thickness import BendingLaw

NOMINAL_LAW = BendingLaw(T, NOMINAL.youngs_modulus_mpa, NOMINAL.poisson, NOMINAL.yield_stress_mpa)


@pytest.fixture(scope="module")
def pressed():
    """A doubly curved bowl pressed twice (the second press further): the grid, cycles, the true curvatures."""
    press, active, design, grid = bowl()
    cycles = [PressedCycle([np.where(active, factor * design, np.nan)], np.zeros(press.shape))
              for factor in (1.5, 1.8)]
    true = replay(TRUE, loaded_curvatures(grid, cycles), cycles).unloaded
    return grid, cycles, true


def test_the_true_material_is_found_from_the_shapes_and_the_change(pressed):
    grid, cycles, true = pressed
    fitted = calibrate(grid, NOMINAL_LAW, cycles, true).law
    assert fitted.yield_stress_mpa == pytest.approx(275.0, rel=0.03)
    first = calibrate(grid, NOMINAL_LAW, cycles[:1], true[:1])
    assert first.law.yield_stress_mpa == pytest.approx(275.0, rel=0.03)
    assert np.isnan(first.secant_misfit_mm)  # one cycle: no change to fit


@pytest.mark.parametrize("response", [3.0, 0.3])
def test_a_plate_answering_unlike_the_model_is_not_taken_for_another_steel(pressed, response):
    grid, cycles, true = pressed
    shown = [true[0], true[0] + response * (true[1] - true[0])]  # the second press moved the plate 3 (0.3) x as far
    first = calibrate(grid, NOMINAL_LAW, cycles[:1], shown[:1]).law
    fitted = calibrate(grid, NOMINAL_LAW, cycles, shown)
    # the first shape is the plate's material; the change cannot pull the yield stress far from it
    assert fitted.law.yield_stress_mpa == pytest.approx(first.yield_stress_mpa, rel=0.05)
    assert fitted.law.yield_stress_mpa == pytest.approx(275.0, rel=0.1)  # unbounded: 227 (3 x), 329 MPa (0.3 x)
    # what the material does not explain stays in the misfit of the change (for the learned response)
    assert fitted.secant_misfit_mm > 0.3 * fitted.change_mm
