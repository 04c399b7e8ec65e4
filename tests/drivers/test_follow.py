"""The driver's readings for a watcher (the panel): setpoints and per-punch fault bits, decoded from the registers."""

from __future__ import annotations

import numpy as np
import pytest

from driver_helpers import running_sim, small_press, step_setpoints

from mppf.core.errors import PressFault
from mppf.drivers.modbus import ModbusPress


@pytest.fixture
def press():
    return small_press()


@pytest.fixture
def sim(press):
    yield from running_sim(press)


def test_the_setpoints_read_back_are_those_pressed(sim, press):
    upper, lower = step_setpoints(press, seed=3)
    with ModbusPress(sim.url, press) as plc:
        plc.run_step(upper, lower)
    with ModbusPress(sim.url, press, heartbeat_s=None) as watcher:  # a reader: no claim, no heartbeat
        read = watcher.read_setpoints_mm()
        faults = watcher.read_fault_bits()
    assert set(read) == {"upper", "lower"} and read["upper"].shape == press.shape
    np.testing.assert_allclose(read["upper"], upper, atol=0.005)  # one count is 0.01 mm
    np.testing.assert_allclose(read["lower"], lower, atol=0.005)
    np.testing.assert_allclose(read["lower"], sim.setpoints_mm()[1], atol=1e-9)
    assert faults["upper"].dtype == bool and not faults["upper"].any() and not faults["lower"].any()


def test_the_fault_bit_of_a_stuck_punch_is_read_at_that_punch(sim, press):
    upper, lower = step_setpoints(press)
    sim.inject("stuck", matrix="upper", row=0, col=1, percent=30, fault_after_s=0.5)
    with ModbusPress(sim.url, press) as plc, pytest.raises(PressFault):
        plc.run_step(upper, lower)
    with ModbusPress(sim.url, press, heartbeat_s=None) as watcher:
        faults = watcher.read_fault_bits()
    assert faults["upper"][0, 1]
    assert int(faults["upper"].sum()) == 1 and not faults["lower"].any()
