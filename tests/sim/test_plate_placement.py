"""The steel plate shifted on the bed between sections (:meth:`mppf.sim.plate.plate.SteelPlate.place`)."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.scanner import PressedStep
from mppf.model.press import example_press_path, load_press
from mppf.sim.plate.plate import SteelPlate
from mppf.sim.shop import SimulatedPlateScanner

PRESS = load_press(example_press_path())
LONG = np.array([[-1800.0, -700.0], [2900.0, -700.0], [2900.0, 700.0], [-1800.0, 700.0]])  # longer than the bed


def _bowl(plate, depth_mm, centre_x_mm):
    """Tips pressing a bowl of ``depth_mm`` centred at plate x ``centre_x_mm`` (in press x: minus the placement)."""
    x, y = np.meshgrid(PRESS.punch_x_mm, PRESS.punch_y_mm)
    x = x + plate.placement_mm[0] - centre_x_mm
    lower = depth_mm * ((x / 1700.0) ** 2 + (y / 1100.0) ** 2)
    return lower + 20.0, lower, np.ones(PRESS.shape, dtype=bool)


def test_placing_moves_the_punches_and_the_plate_keeps_its_shape():
    plate = SteelPlate(PRESS, LONG, 20.0, seed=None, grid_spacing_mm=150.0)
    first = plate.punches.xy_mm.copy()
    plate.press_step(*_bowl(plate, 60.0, 0.0))
    before = plate.formed.height_mm(np.array([-1500.0, 0.0, 1500.0, 2700.0]), np.zeros(4))
    plate.place((1050.0, 0.0))
    # the punch axes now lie 1050 mm further along the plate: the +x end, out of reach before, is over punches
    assert plate.punches.xy_mm[:, 0].max() == pytest.approx(first[:, 0].max() + 1050.0)
    assert first[:, 0].max() < 2000.0 < plate.punches.xy_mm[:, 0].max()
    after = plate.formed.height_mm(np.array([-1500.0, 0.0, 1500.0, 2700.0]), np.zeros(4))
    assert np.allclose(before, after)
    # every pair touches the plate as it lies: the gaps are zero
    gaps = plate.punches.gaps(plate.q, plate.tips_lower_mm, plate.tips_upper_mm)[0]
    assert np.abs(gaps).max() < 1e-9


def test_the_second_section_bends_the_plate_beyond_the_first_sections_reach():
    plate = SteelPlate(PRESS, LONG, 20.0, seed=None, grid_spacing_mm=150.0)
    plate.press_step(*_bowl(plate, 250.0, 0.0))  # R about 6 m: bent plastically
    end = np.array([2850.0, 2600.0, 2350.0])
    once = plate.formed.height_mm(end, np.zeros(3))
    bend_once = np.diff(np.diff(once))[0]  # second difference over 250 mm: > 0 bent like the bowl
    assert bend_once < 0.5  # out of the first section's reach: not bent like the bowl
    plate.place((1050.0, 0.0))
    plate.press_step(*_bowl(plate, 250.0, 1050.0))
    twice = plate.formed.height_mm(end, np.zeros(3))
    assert np.diff(np.diff(twice))[0] > bend_once + 2.0  # the second section bent it like the bowl
    # saved and restored, the plate keeps its placement and shape
    again = SteelPlate.from_state(plate.state_dict())
    assert np.allclose(again.placement_mm, plate.placement_mm)
    assert np.allclose(again.formed.height_mm(end, np.zeros(3)), twice)


def test_the_scanner_presses_each_step_at_its_placement(tmp_path):
    up, lo, active = _bowl(SteelPlate(PRESS, LONG, 20.0, seed=None, grid_spacing_mm=150.0), 40.0, 0.0)
    step = PressedStep(1, 1, up, lo, active)
    shifted = PressedStep(1, 2, up, lo, active)
    object.__setattr__(shifted, "placement_mm", (600.0, 0.0))
    scanner = SimulatedPlateScanner(PRESS, 20.0, LONG, plate_options={"grid_spacing_mm": 150.0})
    scanner._press(step)
    assert np.allclose(scanner.plate.placement_mm, 0.0)
    scanner._press(shifted)
    assert np.allclose(scanner.plate.placement_mm, (600.0, 0.0))
