"""Stroke compensation on the plate model (one virtual cycle's step): sign, gain, unknown errors, bad inputs."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import InputError
from mppf.correct.compensate import CompensateOptions, compensate
from mppf.model.material import Material
from plan_helpers import grid, press  # noqa: F401 (fixtures)

THICKNESS_MM = 20.0
STEEL = Material()


def _bowl(px, active, depth_mm=2.0):
    """A deviation that bends along x: ``depth_mm`` at the block's ends in x, 0 in the middle (mm)."""
    return np.where(active, depth_mm * (px / 1500.0) ** 2, np.nan)


def test_a_bend_above_the_design_is_bent_back_and_the_gain_scales_the_step(press, grid):
    px, py, active, lower = grid
    upper = lower + THICKNESS_MM
    error = _bowl(px, active)  # the plate's ends lie above the design
    corr = compensate(upper, lower, error, press=press, thickness_mm=THICKNESS_MM, material=STEEL,
                      options=CompensateOptions(smoothing=0.0))
    # the ends go down against the middle (the correction's plane is free: compare shapes)
    ends, middle = active & (np.abs(px) >= 1200), active & (np.abs(px) <= 300)
    assert corr.applied_mm[ends].mean() < corr.applied_mm[middle].mean() - 1.0
    assert np.allclose((corr.upper_mm - corr.lower_mm)[active], THICKNESS_MM)
    assert np.all(np.isnan(corr.lower_mm[~active])) and np.all(corr.applied_mm[~active] == 0)
    # half the gain, half the step (well inside the limits and the trust region)
    half = compensate(upper, lower, 0.5 * error, press=press, thickness_mm=THICKNESS_MM, material=STEEL,
                      options=CompensateOptions(smoothing=0.0, gain=0.5))
    assert not corr.clipped.any() and not half.clipped.any()
    assert np.allclose(half.applied_mm[active], 0.25 * corr.applied_mm[active], atol=1e-6)
    assert np.allclose(half.gain[active], 0.5)


def test_no_known_deviation_gives_no_correction(press, grid):
    px, py, active, lower = grid
    corr = compensate(lower + THICKNESS_MM, lower, np.full(press.shape, np.nan), press=press,
                      thickness_mm=THICKNESS_MM, material=STEEL)
    assert np.all(corr.applied_mm == 0.0)
    assert np.allclose(corr.lower_mm[active], lower[active])


def test_bad_inputs_are_refused(press, grid):
    px, py, active, lower = grid
    with pytest.raises(InputError, match="shape"):
        compensate(lower[:, :3], lower, lower, press=press, thickness_mm=20.0, material=STEEL)
    with pytest.raises(InputError, match="gain"):
        compensate(lower, lower, lower, press=press, thickness_mm=20.0, material=STEEL,
                   options=CompensateOptions(gain=0.0))
    with pytest.raises(InputError, match="smoothing"):
        compensate(lower, lower, lower, press=press, thickness_mm=20.0, material=STEEL,
                   options=CompensateOptions(smoothing=1.5))
