"""Displacement adjustment with the secant gain: convergence on a linear plant, fall-backs, clipping."""

from __future__ import annotations

import numpy as np

from mppf.correct.compensate import CompensateOptions, compensate
from mppf.correct.displacement import GAIN_RANGE
from mppf.correct.result import PreviousCycle
from plan_helpers import grid, press  # noqa: F401 (fixtures)

THICKNESS_MM = 20.0


def test_secant_gain_converges_on_a_linear_plant(press, grid):
    """Plant e = g (h - h*) with an unknown gain g per punch (0.4..0.8): DA + secant converges."""
    px, py, active, target = grid
    g = np.where(active, 0.6 + 0.2 * np.sin(px / 700.0) * np.cos(py / 500.0), np.nan)
    lower = target + np.where(active, 8.0 + 0.001 * px + 2e-6 * py**2, np.nan)  # first strokes: off

    def plant(h):
        return g * (h - target)

    previous = None
    history, gains = [], []
    for _ in range(5):
        error = plant(lower)
        history.append(np.nanmax(np.abs(error)))
        corr = compensate(lower + THICKNESS_MM, lower, error, press=press, thickness_mm=THICKNESS_MM, previous=previous)
        previous = PreviousCycle(lower_mm=lower, punch_error_mm=error)
        gains.append(corr.gain)
        lower = corr.lower_mm
    history.append(np.nanmax(np.abs(plant(lower))))
    assert history[0] > 3.0
    assert history[-1] < 0.05 * history[0]
    assert all(b < a for a, b in zip(history, history[1:]))
    # cycle 2: the secant follows the inverse plant gain 1/g (half own, half plate-wide secant)
    assert np.allclose(gains[0][active], 1.0)
    assert np.corrcoef(gains[1][active], 1.0 / g[active])[0, 1] > 0.95
    assert np.median(np.abs(gains[1][active] * g[active] - 1.0)) < 0.15
    # default gain 1 alone (no secant) converges more slowly
    lower_da = target + np.where(active, 8.0 + 0.001 * px + 2e-6 * py**2, np.nan)
    for _ in range(5):
        lower_da = compensate(lower_da + THICKNESS_MM, lower_da, plant(lower_da), press=press,
                              thickness_mm=THICKNESS_MM).lower_mm
    assert np.nanmax(np.abs(plant(lower_da))) > history[-1]


def test_uniform_plant_gain_is_recovered_exactly(press, grid):
    px, py, active, target = grid
    offset = np.where(active, 5.0 + 0.002 * px, np.nan)
    h0, h1 = target + offset, target + 0.4 * offset  # two cycles of a plant with g = 0.7
    corr = compensate(h1 + THICKNESS_MM, h1, 0.7 * (h1 - target), press=press, thickness_mm=THICKNESS_MM,
                      previous=PreviousCycle(lower_mm=h0, punch_error_mm=0.7 * (h0 - target)),
                      options=CompensateOptions(smoothing=0.0))
    assert np.allclose(corr.gain[active], 1 / 0.7)
    assert np.allclose(corr.lower_mm[active], target[active])


def test_secant_falls_back_and_clips(press, grid):
    px, py, active, lower = grid
    error = np.where(active, 1.0, np.nan)
    # no stroke change since the last cycle: the secant is undefined, the default gain is used
    corr = compensate(lower + THICKNESS_MM, lower, error, press=press, thickness_mm=THICKNESS_MM,
                      previous={"lower_mm": lower, "punch_error_mm": error + 0.5}, options=CompensateOptions(gain=1.2))
    assert np.allclose(corr.gain[active], 1.2)
    # a huge apparent gain is clipped to the range
    corr = compensate(lower + THICKNESS_MM, lower, error, press=press, thickness_mm=THICKNESS_MM,
                      previous=PreviousCycle(lower_mm=lower - 10.0, punch_error_mm=error - 0.2))
    assert np.allclose(corr.gain[active], GAIN_RANGE[1])
    # a wrong-signed secant (the plate moved against the punch) falls back to the default
    corr = compensate(lower + THICKNESS_MM, lower, error, press=press, thickness_mm=THICKNESS_MM,
                      previous=PreviousCycle(lower_mm=lower - 1.0, punch_error_mm=error + 1.0))
    assert np.allclose(corr.gain[active], 1.0)
