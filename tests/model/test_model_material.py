"""The plate material (``mppf/model/material.py``): checked constants, plane-strain values, named materials."""

from __future__ import annotations

import pytest

from mppf.core.errors import InputError
from mppf.model.material import MATERIALS, Material


@pytest.mark.parametrize(("field", "value", "named"), [
    ("youngs_modulus_mpa", 0.0, "Young's modulus"),
    ("youngs_modulus_mpa", float("nan"), "Young's modulus"),
    ("poisson", 0.5, "Poisson's ratio"),
    ("poisson", -0.1, "Poisson's ratio"),
    ("yield_stress_mpa", -235.0, "the yield stress"),
    ("yield_stress_mpa", "235 MPa", "the yield stress"),
])
def test_a_constant_out_of_its_range_is_named_with_the_value(field, value, named):
    with pytest.raises(InputError) as info:
        Material(**{field: value})
    assert named in info.value.message


def test_plane_strain_values_and_the_named_steels():
    steel = Material(youngs_modulus_mpa=200000, poisson=0.3, yield_stress_mpa=300)
    assert isinstance(steel.youngs_modulus_mpa, float)
    assert steel.plane_strain_modulus_mpa == pytest.approx(200000 / 0.91)
    assert steel.plane_strain_yield_mpa == pytest.approx(346.5)
    assert MATERIALS["steel"] == Material() and MATERIALS["ah36"].yield_stress_mpa == 355.0


def test_the_forming_stage_works_on_the_same_class():
    from mppf.forming.material import weakest_material

    weaker = weakest_material(MATERIALS["ah36"], 10.0)
    assert type(weaker) is Material and weaker.yield_stress_mpa == pytest.approx(319.5)
