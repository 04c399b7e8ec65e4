"""The tilt's linear programme on an active set gives the plane of the programme on every row."""

import numpy as np
import pytest
from scipy.optimize import linprog

from mppf.planning.pose import minimax_offset


def _full_programme(dev, x, y, low, high, max_slope):
    """The programme on every row, as written in the docstring of minimax_offset (unscaled)."""
    ones, zero = np.ones_like(dev), np.zeros_like(dev)
    plane = np.column_stack([x, y, ones])
    a_ub = np.vstack([np.column_stack([plane, -ones]), np.column_stack([-plane, -ones]),
                      np.column_stack([plane, zero]), np.column_stack([-plane, zero])])
    b_ub = np.concatenate([-dev, dev, high - dev, dev - low])
    res = linprog([0, 0, 0, 1], A_ub=a_ub, b_ub=b_ub, method="highs",
                  bounds=[(-max_slope, max_slope), (-max_slope, max_slope), (None, None), (0, None)])
    return res.x if res.status == 0 else None


@pytest.mark.parametrize("seed", range(6))
def test_active_set_matches_the_full_programme(seed):
    rng = np.random.default_rng(seed)
    x, y = (g.ravel() for g in np.meshgrid(np.arange(-1725.0, 1726.0, 150.0), np.arange(-1125.0, 1126.0, 150.0)))
    x, y = np.concatenate([x, x]), np.concatenate([y, y])  # both matrices
    curvature = rng.uniform(-1.0, 1.0, 3) / 20000.0
    dev = curvature[0] * x**2 + curvature[1] * y**2 + curvature[2] * x * y + rng.uniform(-0.02, 0.03) * x
    dev += rng.normal(0.0, 0.5, dev.size)
    low, high = np.full(dev.size, -60.0), np.full(dev.size, rng.uniform(30.0, 200.0))
    got = minimax_offset(dev, x, y, low, high, max_slope=0.05)
    want = _full_programme(dev, x, y, low, high, 0.05)
    if want is None:
        assert got is None
        return
    assert got is not None
    assert abs(got[3] - want[3]) < 1e-6  # the same largest travel
    travel = dev + got[0] * x + got[1] * y + got[2]
    assert np.all(travel <= high + 1e-6) and np.all(travel >= low - 1e-6)
    assert abs(np.abs(travel).max() - want[3]) < 1e-6


def test_infeasible_limits_give_none():
    x, y = (g.ravel() for g in np.meshgrid(np.arange(0.0, 3000.0, 150.0), np.arange(0.0, 2000.0, 150.0)))
    dev = (x - 1500.0) ** 2 / 10000.0  # 225 mm of bow, no tilt removes it
    assert minimax_offset(dev, x, y, np.full(dev.size, -50.0), np.full(dev.size, 50.0), max_slope=0.05) is None
