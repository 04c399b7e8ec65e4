"""The over-bend of the two principal directions together (``mppf.planning.sectional_overbend.biaxial_loaded``).

Checked against the plate's biaxial bending law (``mppf.correct.through_thickness.BendingLaw``) it inverts, and
against the textbook anticlastic springback: a plate bent along one direction and held flat across springs back
with a curvature across of the other sense.
"""

from __future__ import annotations

import numpy as np
import pytest

from mppf.correct.through_thickness import BendingLaw, BendingState
from mppf.forming.springback import loaded_curvature
from mppf.model.material import Material
from mppf.planning.sectional_overbend import biaxial_loaded

T_MM = 20.0
STEEL = Material()


def _released(k):
    law = BendingLaw(T_MM, STEEL.youngs_modulus_mpa, STEEL.poisson, STEEL.yield_stress_mpa)
    return law.press(np.array([[k[0], k[1], 0.0]]), BendingState.virgin(1))[0][0, :2]


def _uniaxial(target):
    target = np.asarray(target, dtype=float)
    return np.where(target == 0.0, 0.0, loaded_curvature(np.where(target == 0.0, 1e-9, target), T_MM, STEEL))


def test_held_flat_across_a_bend_springs_back_anticlastic():
    """R 20 m along, held flat across: the release leaves a curvature across of the other sense, a bow of about
    6 mm over 2.4 m (the law's, independent of the planner)."""
    along = float(loaded_curvature(np.array([1.0 / 20000.0]), T_MM, STEEL)[0])
    released = _released([along, 0.0])
    bow_mm = released[1] * 2400.0**2 / 8.0
    assert released[1] < 0.0 and -8.0 < bow_mm < -4.0


@pytest.mark.parametrize("target", [(1 / 20000.0, 0.0), (1 / 10000.0, 0.0), (1 / 10000.0, 1 / 20000.0),
                                    (1 / 75000.0, -1 / 75000.0), (-1 / 6000.0, 1 / 100000.0)])
def test_the_loaded_curvatures_release_to_the_target_in_both_directions(target):
    target = np.array(target)
    loaded = biaxial_loaded(target, _uniaxial(target), T_MM, STEEL)
    assert np.allclose(_released(loaded), target, rtol=0.0, atol=1e-3 * np.abs(target).max())
    # a cylinder is over-bent across in its own sense, to cancel the anticlastic springback
    if target[1] == 0.0:
        assert loaded[1] * target[0] > 0.0


def test_a_flat_plate_is_not_bent():
    assert np.array_equal(biaxial_loaded(np.zeros(2), np.zeros(2), T_MM, STEEL), np.zeros(2))
