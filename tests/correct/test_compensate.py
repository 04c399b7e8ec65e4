"""Stroke compensation (the orchestrating compensate): sign convention, unknown errors, bad inputs."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import InputError
from mppf.correct.compensate import CompensateOptions, compensate
from plan_helpers import grid, press  # noqa: F401 (fixtures)

THICKNESS_MM = 20.0


def test_positive_error_lowers_both_matrices_by_gain_times_error(press, grid):
    px, py, active, lower = grid
    upper = lower + THICKNESS_MM
    error = np.where(active, 2.0, np.nan)  # the plate lies 2 mm above the design everywhere
    corr = compensate(upper, lower, error, press=press, thickness_mm=THICKNESS_MM, options=CompensateOptions(gain=1.5))
    assert np.allclose(corr.applied_mm[active], -3.0)
    assert np.allclose(corr.lower_mm[active], lower[active] - 3.0)
    assert np.allclose((corr.upper_mm - corr.lower_mm)[active], THICKNESS_MM)
    assert np.all(np.isnan(corr.lower_mm[~active])) and np.all(corr.applied_mm[~active] == 0)
    assert not corr.clipped.any()
    assert np.allclose(corr.gain[active], 1.5)
    # negative error (plate below the design) raises the punches
    corr = compensate(upper, lower, -error, press=press, thickness_mm=THICKNESS_MM)
    assert np.allclose(corr.applied_mm[active], 2.0)


def test_unknown_error_gives_no_correction(press, grid):
    px, py, active, lower = grid
    error = np.where(active, 1.0, np.nan)
    error[active & (px > 0)] = np.nan
    corr = compensate(lower + THICKNESS_MM, lower, error, press=press, thickness_mm=THICKNESS_MM,
                      options=CompensateOptions(smoothing=0.0))
    assert np.all(corr.applied_mm[active & (px > 0)] == 0.0)
    assert np.allclose(corr.applied_mm[active & (px < 0)], -1.0)


def test_bad_inputs_are_refused(press, grid):
    px, py, active, lower = grid
    with pytest.raises(InputError, match="shape"):
        compensate(lower[:, :3], lower, lower, press=press, thickness_mm=20.0)
    with pytest.raises(InputError, match="gain"):
        compensate(lower, lower, lower, press=press, thickness_mm=20.0, options=CompensateOptions(gain=0.0))
    with pytest.raises(InputError, match="previous"):
        compensate(lower, lower, lower, press=press, thickness_mm=20.0, previous={"lower_mm": lower})
