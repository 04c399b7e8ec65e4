"""The one interface of the simulated plates (mppf.sim.simulated_plate): both plates the shop offers implement it."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from mppf.core.errors import InputError
from mppf.model.press import example_press_path, load_press
from mppf.sim.fe.plate import FEPlate
from mppf.sim.plate.plate import SteelPlate
from mppf.sim.shop import PLATE_MODELS, SimulatedPlateScanner
from mppf.sim.simulated_plate import SimulatedPlate

PRESS = load_press(example_press_path())
OUTLINE = np.array([[-900.0, -500.0], [900.0, -500.0], [900.0, 500.0], [-900.0, 500.0]])


@pytest.mark.parametrize("plate_class", [SteelPlate, FEPlate])
def test_each_plate_class_has_the_interfaces_calls_with_its_parameters(plate_class):
    for name in ("place", "press_step", "state_dict"):
        wanted = inspect.signature(getattr(SimulatedPlate, name)).parameters
        given = inspect.signature(getattr(plate_class, name)).parameters
        assert list(given)[: len(wanted)] == list(wanted), name
        assert all(given[p].default == wanted[p].default for p in wanted), name
    assert isinstance(inspect.getattr_static(plate_class, "formed"), property)
    assert isinstance(inspect.getattr_static(plate_class, "from_state"), classmethod)


def test_both_plates_are_simulated_plates_and_only_the_steel_one_is_pressed_in_sections():
    steel = SteelPlate(PRESS, OUTLINE, 20.0, seed=None, grid_spacing_mm=150.0)
    fe = FEPlate(PRESS, OUTLINE, 20.0, seed=None)
    assert isinstance(steel, SimulatedPlate) and isinstance(fe, SimulatedPlate)
    steel.place((600.0, 0.0))
    assert np.allclose(steel.placement_mm, (600.0, 0.0))
    fe.place((0.0, 0.0))  # the first placement
    with pytest.raises(InputError, match=r"cannot be pressed in sections.*\[600\.0, 0\.0\]"):
        fe.place((600.0, 0.0))


def test_the_shop_offers_the_two_plates_the_steel_one_by_default():
    """(The shop's FE plate needs CalculiX: tests/sim/test_fe_shop.py, slow.)"""
    assert PLATE_MODELS == ("steel", "fe")
    scanner = SimulatedPlateScanner(PRESS, 20.0, OUTLINE, seed=1, plate_options={"grid_spacing_mm": 150.0})
    assert type(scanner.plate) is SteelPlate and isinstance(scanner.plate, SimulatedPlate)
