"""Hydraulic punch motion: trapezoidal profiles and braking."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.sim.hydraulics import Hydraulics


def run_until_rest(hyd, dt_s=0.001, limit_s=20.0):
    t = 0.0
    while hyd.moving:
        hyd.step(dt_s)
        t += dt_s
        assert t < limit_s
    return t


@pytest.mark.parametrize(
    "distance_mm, expected_s",
    [
        (100.0, 100.0 / 20.0 + 20.0 / 100.0),  # trapezoid: cruise at 20 mm/s, 0.2 s to accelerate
        (1.0, 2.0 * np.sqrt(1.0 / 100.0)),  # triangle: never reaches full speed
    ],
)
def test_trapezoidal_motion_time(distance_mm, expected_s):
    hyd = Hydraulics(np.zeros((2, 1, 2)), speed_mm_s=20.0, accel_mm_s2=100.0)
    target = np.array([[[distance_mm, -distance_mm]], [[0.0, distance_mm / 2]]])
    hyd.move_to(target)
    assert run_until_rest(hyd) == pytest.approx(expected_s, rel=0.02)
    assert np.array_equal(hyd.position, target)


def test_stop_brakes_within_the_braking_distance():
    hyd = Hydraulics(np.zeros((2, 1, 1)), speed_mm_s=20.0, accel_mm_s2=100.0)
    hyd.move_to(np.full((2, 1, 1), 100.0))
    for _ in range(1000):  # 1 s: at full speed
        hyd.step(0.001)
    at_stop = hyd.position.copy()
    hyd.stop()
    run_until_rest(hyd)
    braked = hyd.position - at_stop
    assert np.allclose(braked, 20.0**2 / (2 * 100.0), atol=0.05)  # v^2 / 2a = 2 mm
