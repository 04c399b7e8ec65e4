"""The learned response: smooth modes by Broyden's rule, and a local ratio per punch for what modes cannot follow
(a plate edge that answers a stroke change differently from the interior)."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.correct.punch_grid import PunchGrid
from mppf.correct.secant import LOCAL_RANGE, ModeGain
from mppf.model.press import example_press_path, load_press


@pytest.fixture(scope="module")
def grid():
    press = load_press(example_press_path())
    active = np.zeros(press.shape, dtype=bool)
    active[2:10, 3:15] = True
    return PunchGrid(press, active)


def _bowl(grid, depth_mm):
    x, y = grid.x_mm, grid.y_mm
    act = grid.active
    z = ((x - x[act].mean()) / np.ptp(x[act])) ** 2 + 0.5 * ((y - y[act].mean()) / np.ptp(y[act])) ** 2
    return np.where(act, grid.flat(np.where(act, depth_mm * z, np.nan)), 0.0)


def test_a_plate_that_answers_as_the_model_teaches_nothing(grid):
    gain = ModeGain(grid)
    model = _bowl(grid, 10.0)
    assert gain.update(model, model)
    np.testing.assert_allclose(gain.gains, 1.0, atol=1e-9)
    np.testing.assert_allclose(gain.local[grid.active], 1.0, atol=1e-9)
    wanted = _bowl(grid, -2.0)
    np.testing.assert_allclose(gain.model_request(wanted)[grid.active], wanted[grid.active], atol=1e-9)


def test_an_edge_that_answers_more_than_the_model_is_learned_locally(grid):
    act = grid.active
    rows, cols = np.flatnonzero(act.any(axis=1)), np.flatnonzero(act.any(axis=0))
    edge = np.zeros_like(act)
    edge[rows[1]:rows[3], cols[-1]] = True  # two punches of the last active column
    ratio = np.where(edge, 2.0, 1.0)
    model = _bowl(grid, 10.0) + np.where(edge, 3.0, 0.0)  # a change the edge makes, more than modes describe
    plate = np.where(act, grid.flat(np.where(act, ratio * model, np.nan)), 0.0)
    gain = ModeGain(grid)
    gain.update(model, plate)
    local = gain.local
    assert local[edge].mean() > 1.2  # the edge answers more (shrunk towards its neighbours and 1)
    inner = act & (np.arange(act.shape[1])[None, :] < cols[-3])
    assert abs(local[inner].mean() - 1.0) < 0.15  # ... the interior as the modes say
    assert local[act].min() >= LOCAL_RANGE[0] and local[act].max() <= LOCAL_RANGE[1]
    # the learned response explains the secant far better than the modes alone
    modes_only = ModeGain(grid)
    modes_only.update(model, plate)
    modes_only.local = np.ones(grid.shape)
    miss = np.sqrt(np.mean((gain.plate_response(model) - plate)[act] ** 2))
    miss_modes = np.sqrt(np.mean((modes_only.plate_response(model) - plate)[act] ** 2))
    assert miss < 0.7 * miss_modes
    # asked for a change at the edge, the model is asked for less there
    wanted = np.where(edge, -1.0, 0.0)
    request = gain.model_request(wanted)
    assert np.mean(np.abs(request[edge])) < 0.8 * np.mean(np.abs(grid.flat(np.where(act, wanted, np.nan))[edge]))


def test_small_secants_are_noise(grid):
    gain = ModeGain(grid)
    assert not gain.update(_bowl(grid, 0.1), _bowl(grid, 0.5))
    assert gain.updates == 0 and np.all(gain.local == 1.0)
