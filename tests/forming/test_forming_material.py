"""The declared yield scatter (mppf.forming.material): checked once, the weakest plate of the range planned for."""

from __future__ import annotations

import pytest

from mppf.core.errors import InputError
from mppf.forming.material import MAX_YIELD_UNCERTAINTY_PCT, check_yield_uncertainty, weakest_material
from mppf.model.material import MATERIALS


@pytest.mark.parametrize("pct", [0, 0.0, 10, 49.9])
def test_a_scatter_from_0_to_below_50_percent_is_taken(pct):
    assert check_yield_uncertainty(pct) == float(pct) and isinstance(check_yield_uncertainty(pct), float)


@pytest.mark.parametrize("pct", [-1.0, MAX_YIELD_UNCERTAINTY_PCT, 80.0, float("nan"), "10", True])
def test_a_scatter_out_of_range_is_refused_naming_the_option_and_the_value(pct):
    with pytest.raises(InputError, match="--yield-uncertainty") as caught:
        check_yield_uncertainty(pct)
    assert "mill certificate" in caught.value.hint


def test_the_weakest_plate_has_only_its_yield_stress_lowered():
    steel = MATERIALS["steel"]
    weakest = weakest_material(steel, 10.0)
    assert weakest.yield_stress_mpa == pytest.approx(0.9 * steel.yield_stress_mpa)
    assert (weakest.youngs_modulus_mpa, weakest.poisson) == (steel.youngs_modulus_mpa, steel.poisson)
    assert weakest_material(steel, 0.0) is steel
    with pytest.raises(InputError):
        weakest_material(steel, 60.0)
