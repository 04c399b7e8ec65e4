"""Springback pre-compensation by virtual press cycles on the plate model."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mppf.core.errors import InputError
from mppf.forming.precompensate import _deviation, calibrated_correction, fit_yield_stress, predict_mid_heights, refine_strokes
from mppf.planning.press import example_press_path, load_press
from mppf.forming.material import Material
from mppf.forming.springback import unloaded_curvature

T = 20.0
PRESS = dataclasses.replace(load_press(example_press_path()), margin_mm=0.0)
STEEL = Material()


def _grid(active_cols=slice(2, 22), active_rows=slice(1, 15)):
    px, py = np.meshgrid(PRESS.punch_x_mm, PRESS.punch_y_mm)
    active = np.zeros(PRESS.shape, dtype=bool)
    active[active_rows, active_cols] = True
    outline = np.array([[px[active].min() - 50, py[active].min() - 50], [px[active].max() + 50, py[active].min() - 50],
                        [px[active].max() + 50, py[active].max() + 50], [px[active].min() - 50, py[active].max() + 50]])
    return px, py, active, outline


def test_a_sharp_cylinder_springs_back_by_the_law_in_the_middle():
    px, py, active, outline = _grid()
    k = 1.0 / 2500.0  # loaded radius 2.5 m: plastic
    mid = np.where(active, py**2 * k / 2.0, np.nan)
    predicted = predict_mid_heights(PRESS, mid + T / 2, mid - T / 2, active, outline, T, STEEL)
    inner = active & (np.abs(py) <= 600) & (np.abs(px) <= 1200)
    kf = float(unloaded_curvature(k, T, STEEL))
    curvature = np.gradient(np.gradient(predicted, PRESS.pitch_y_mm, axis=0), PRESS.pitch_y_mm, axis=0)
    assert 0.1 * k < kf < 0.9 * k
    assert np.allclose(curvature[inner], kf, rtol=0.05)


def test_refinement_brings_the_predicted_plate_onto_the_target():
    px, py, active, outline = _grid()
    target = np.where(active, py**2 / (2 * 6000.0) + px * py / 2.0e7, np.nan)  # a twisted bilge
    result = refine_strokes(PRESS, target + T / 2, target - T / 2, active, target, outline, T, STEEL)
    assert result.history_mm[0] > 5.0  # pressing the design itself springs back far off
    assert result.predicted_max_mm < 0.5  # from 40+ mm
    assert len(result.history_mm) >= 3
    assert np.all(np.isnan(result.upper_mm[~active])) and np.all(np.isfinite(result.upper_mm[active]))
    # the gap stays the plate thickness, and the strokes stay sane (no runaway step)
    np.testing.assert_allclose((result.upper_mm - result.lower_mm)[active], T)
    step = result.lower_mm
    assert np.nanmax(np.abs(np.diff(step, axis=1))) < 200


def test_zero_iterations_only_predict():
    px, py, active, outline = _grid()
    target = np.where(active, py**2 / (2 * 6000.0), np.nan)
    result = refine_strokes(PRESS, target + T / 2, target - T / 2, active, target, outline, T, STEEL, iterations=0)
    assert len(result.history_mm) == 1
    np.testing.assert_allclose(result.lower_mm[active], (target - T / 2)[active])


@pytest.mark.parametrize("iterations, tolerance", [(-1, 0.1), (3, 0.0), (3, float("nan"))])
def test_bad_refinement_settings(iterations, tolerance):
    px, py, active, outline = _grid()
    target = np.where(active, 0.0, np.nan)
    with pytest.raises(InputError, match="refinement"):
        refine_strokes(PRESS, target + T / 2, target - T / 2, active, target, outline, T, STEEL,
                       iterations=iterations, tolerance_mm=tolerance)


def _softer_plate_pressed():
    """Strokes refined for the nominal steel; the plate that took them is 15 % softer."""
    px, py, active, outline = _grid()
    target = np.where(active, py**2 / (2 * 6000.0) + px * py / 2.0e7, np.nan)
    planned = refine_strokes(PRESS, target + T / 2, target - T / 2, active, target, outline, T, STEEL)
    true = Material(yield_stress_mpa=0.85 * STEEL.yield_stress_mpa)
    formed = predict_mid_heights(PRESS, planned.upper_mm, planned.lower_mm, active, outline, T, true)
    measured = _deviation(PRESS, formed, target, active)
    return px, py, active, outline, target, planned, true, measured


def test_the_effective_yield_stress_is_found_from_one_measured_cycle():
    px, py, active, outline, target, planned, true, measured = _softer_plate_pressed()
    assert np.nanmax(np.abs(measured)) > 2.0  # the softer plate is measurably off
    noisy = measured + np.where(active, np.random.default_rng(0).normal(0.0, 0.3, measured.shape), np.nan)
    fit = fit_yield_stress(PRESS, [(planned.upper_mm, planned.lower_mm, noisy)], active, target, outline, T, STEEL)
    assert fit.material.yield_stress_mpa == pytest.approx(true.yield_stress_mpa, abs=4.0)
    assert fit.cost_fit_mm2 < 0.2 * fit.cost_nominal_mm2
    assert fit.explained > 0.8


def test_the_calibrated_correction_brings_the_true_plate_onto_the_design():
    px, py, active, outline, target, planned, true, measured = _softer_plate_pressed()
    refined, fit = calibrated_correction(PRESS, [(planned.upper_mm, planned.lower_mm, measured)], active, target,
                                         outline, T, STEEL)
    after = _deviation(PRESS, predict_mid_heights(PRESS, refined.upper_mm, refined.lower_mm, active, outline, T, true),
                       target, active)
    assert np.nanmax(np.abs(after)) < 0.25 * np.nanmax(np.abs(measured))
    assert np.nanmax(np.abs(after)) < 0.5
    assert "effective yield stress" in refined.notes[0]
    np.testing.assert_allclose((refined.upper_mm - refined.lower_mm)[active], T)


def test_the_calibrated_correction_needs_a_measured_cycle():
    px, py, active, outline = _grid()
    target = np.where(active, py**2 / (2 * 6000.0), np.nan)
    with pytest.raises(InputError):
        calibrated_correction(PRESS, [], active, target, outline, T, STEEL)
    blind = np.full(PRESS.shape, np.nan)
    with pytest.raises(InputError, match="measured deviation"):
        calibrated_correction(PRESS, [(target + T / 2, target - T / 2, blind)], active, target, outline, T, STEEL)
