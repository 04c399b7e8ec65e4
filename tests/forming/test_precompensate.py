"""Springback pre-compensation by virtual press cycles on the plate model."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import InputError
from mppf.correct.virtual_cycles import refine_strokes
from mppf.forming.precompensate import predict_mid_heights
from mppf.forming.springback import unloaded_curvature
from mppf.model.job_parts import StepStrokes
from plan_helpers import MODEL_THICKNESS_MM as T
from plan_helpers import NOMINAL as STEEL
from plan_helpers import model_grid, model_press, softer_plate_pressed

PRESS = model_press()


def test_a_sharp_cylinder_springs_back_by_the_law_in_the_middle():
    px, py, active, outline = model_grid(PRESS)
    k = 1.0 / 2500.0  # loaded radius 2.5 m: plastic
    mid = np.where(active, py**2 * k / 2.0, np.nan)
    predicted = predict_mid_heights(PRESS, mid + T / 2, mid - T / 2, active, outline, T, STEEL)
    inner = active & (np.abs(py) <= 600) & (np.abs(px) <= 1200)
    kf = float(unloaded_curvature(k, T, STEEL))
    curvature = np.gradient(np.gradient(predicted, PRESS.pitch_y_mm, axis=0), PRESS.pitch_y_mm, axis=0)
    assert 0.1 * k < kf < 0.9 * k
    assert np.allclose(curvature[inner], kf, rtol=0.05)


def test_refinement_brings_the_predicted_plate_onto_the_target():
    # a twisted bilge, refined from the design's own strokes (the plate of the calibration tests)
    plate = softer_plate_pressed()
    active, result = plate.active, plate.planned
    assert result.history_mm[0] > 5.0  # pressing the design itself springs back far off
    assert result.predicted_max_mm < 0.5  # from 40+ mm
    assert len(result.history_mm) >= 3
    assert np.all(np.isnan(result.upper_mm[~active])) and np.all(np.isfinite(result.upper_mm[active]))
    # the gap stays the plate thickness, and the strokes stay sane (no runaway step)
    np.testing.assert_allclose((result.upper_mm - result.lower_mm)[active], T)
    step = result.lower_mm
    assert np.nanmax(np.abs(np.diff(step, axis=1))) < 200


def test_zero_iterations_only_predict():
    px, py, active, outline = model_grid(PRESS)
    target = np.where(active, py**2 / (2 * 6000.0), np.nan)
    result = refine_strokes(PRESS, StepStrokes(target + T / 2, target - T / 2, active), target, outline, T, STEEL,
                            iterations=0)
    assert len(result.history_mm) == 1
    np.testing.assert_allclose(result.lower_mm[active], (target - T / 2)[active])


@pytest.mark.parametrize("iterations, tolerance", [(-1, 0.1), (3, 0.0), (3, float("nan"))])
def test_bad_refinement_settings(iterations, tolerance):
    px, py, active, outline = model_grid(PRESS)
    target = np.where(active, 0.0, np.nan)
    with pytest.raises(InputError, match="refinement"):
        refine_strokes(PRESS, StepStrokes(target + T / 2, target - T / 2, active), target, outline, T, STEEL,
                       iterations=iterations, tolerance_mm=tolerance)
