"""The calibrated correction: the effective yield stress fitted to measured cycles, the next strokes
solved on the calibrated plate model, and the loop's calibrated step held to the press's limits."""

from __future__ import annotations

import numpy as np
import pytest

import mppf.correct.calibrated as calibrated
from mppf.core.errors import GeometryError, InputError
from mppf.correct.calibrated import MIN_EXPLAINED, calibrated_correction, calibrated_step, fit_yield_stress
from mppf.correct.limits import limit_correction
from mppf.correct.result import Correction
from mppf.forming.precompensate import deviation, predict_mid_heights
from mppf.model.job_parts import PlateLayout, StepStrokes
from plan_helpers import MODEL_THICKNESS_MM as T
from plan_helpers import NOMINAL as STEEL
from plan_helpers import model_grid, model_press, neighbour_diffs, softer_plate_pressed

PRESS = model_press()


@pytest.fixture(scope="module")
def plate():
    return softer_plate_pressed()


@pytest.fixture(scope="module")
def corrected(plate):
    """The calibrated correction after the one measured cycle of the softer plate."""
    return calibrated_correction(PRESS, [(plate.planned.upper_mm, plate.planned.lower_mm, plate.measured)],
                                 plate.active, plate.target, plate.outline, T, STEEL)


def _layout(plate, design_mid_mm="target") -> PlateLayout:
    return PlateLayout(outline_mm=plate.outline, net_outline_mm=plate.outline, material=STEEL,
                       design_mid_mm=plate.target if design_mid_mm == "target" else design_mid_mm)


def test_the_effective_yield_stress_is_found_from_one_measured_cycle(plate):
    active, measured = plate.active, plate.measured
    assert np.nanmax(np.abs(measured)) > 2.0  # the softer plate is measurably off
    noisy = measured + np.where(active, np.random.default_rng(0).normal(0.0, 0.3, measured.shape), np.nan)
    fit = fit_yield_stress(PRESS, [(plate.planned.upper_mm, plate.planned.lower_mm, noisy)], active, plate.target,
                           plate.outline, T, STEEL)
    assert fit.material.yield_stress_mpa == pytest.approx(plate.true.yield_stress_mpa, abs=4.0)
    assert fit.cost_fit_mm2 < 0.2 * fit.cost_nominal_mm2
    assert fit.explained > 0.8


def test_the_calibrated_correction_brings_the_true_plate_onto_the_design(plate, corrected):
    active, target, outline, measured = plate.active, plate.target, plate.outline, plate.measured
    refined, fit = corrected
    after = deviation(PRESS, predict_mid_heights(PRESS, refined.upper_mm, refined.lower_mm, active, outline, T,
                                                 plate.true), target, active)
    assert np.nanmax(np.abs(after)) < 0.25 * np.nanmax(np.abs(measured))
    assert np.nanmax(np.abs(after)) < 0.5
    assert "effective yield stress" in refined.notes[0]
    np.testing.assert_allclose((refined.upper_mm - refined.lower_mm)[active], T)


def test_the_calibrated_correction_needs_a_measured_cycle():
    px, py, active, outline = model_grid(PRESS)
    target = np.where(active, py**2 / (2 * 6000.0), np.nan)
    with pytest.raises(InputError):
        calibrated_correction(PRESS, [], active, target, outline, T, STEEL)
    blind = np.full(PRESS.shape, np.nan)
    with pytest.raises(InputError, match="measured deviation"):
        calibrated_correction(PRESS, [(target + T / 2, target - T / 2, blind)], active, target, outline, T, STEEL)


def test_the_calibrated_step_is_the_calibrated_correction_held_to_the_press_limits(plate, corrected, monkeypatch):
    step = StepStrokes(np.asarray(plate.planned.upper_mm), np.asarray(plate.planned.lower_mm), plate.active)
    cycles = [(step.upper_mm, step.lower_mm, plate.measured)]
    seen = []

    def known_result(*args, **kwargs):  # the real result of these inputs (the fixture), without solving again
        seen.append(args)
        return corrected

    monkeypatch.setattr(calibrated, "calibrated_correction", known_result)
    correction = calibrated_step(PRESS, cycles, step, _layout(plate), T, STEEL)
    assert isinstance(correction, Correction)
    press, cycles_seen, active, design_mid, outline, thickness, nominal = seen[0]
    assert press is PRESS and cycles_seen is cycles and thickness == T and nominal is STEEL
    np.testing.assert_array_equal(active, plate.active)
    np.testing.assert_array_equal(design_mid, plate.target)
    np.testing.assert_array_equal(outline, plate.outline)
    # the change to the calibrated strokes, held to the dimpling and stroke limits
    refined, _ = corrected
    act = plate.active
    applied, clipped = limit_correction(PRESS, np.where(act, step.upper_mm, np.nan), np.where(act, step.lower_mm, np.nan),
                                        refined.lower_mm - step.lower_mm)
    np.testing.assert_allclose(correction.applied_mm, applied)
    np.testing.assert_array_equal(correction.clipped, clipped)
    np.testing.assert_allclose(correction.lower_mm[act], step.lower_mm[act] + applied[act])
    np.testing.assert_allclose((correction.upper_mm - correction.lower_mm)[act], T)
    assert np.all(np.isnan(correction.lower_mm[~act])) and np.all(correction.applied_mm[~act] == 0.0)
    assert np.all(correction.gain[act] == 1.0) and np.all(np.isnan(correction.gain[~act]))
    assert neighbour_diffs(correction.applied_mm, act).max() <= PRESS.max_neighbour_diff_mm + 1e-6
    assert correction.notes[:len(refined.notes)] == refined.notes
    # a fit that explains less than MIN_EXPLAINED of the deviations is not trusted: None
    monkeypatch.setattr(calibrated, "MIN_EXPLAINED", corrected[1].explained + 0.01)
    assert calibrated_step(PRESS, cycles, step, _layout(plate), T, STEEL) is None
    assert MIN_EXPLAINED == 0.25


@pytest.mark.parametrize("error", [InputError("too few punches"), GeometryError("no outline")])
def test_the_calibrated_step_is_none_when_the_data_do_not_allow_a_calibration(plate, monkeypatch, error):
    step = StepStrokes(np.asarray(plate.planned.upper_mm), np.asarray(plate.planned.lower_mm), plate.active)

    def refuse(*args, **kwargs):
        raise error

    monkeypatch.setattr(calibrated, "calibrated_correction", refuse)
    assert calibrated_step(PRESS, [(step.upper_mm, step.lower_mm, plate.measured)], step, _layout(plate), T,
                           STEEL) is None


def test_the_calibrated_step_is_none_without_measured_punches_or_design_heights(plate):
    step = StepStrokes(np.asarray(plate.planned.upper_mm), np.asarray(plate.planned.lower_mm), plate.active)
    blind = [(step.upper_mm, step.lower_mm, np.full(PRESS.shape, np.nan))]
    assert calibrated_step(PRESS, blind, step, _layout(plate), T, STEEL) is None  # the real InputError
    measured = [(step.upper_mm, step.lower_mm, plate.measured)]
    assert calibrated_step(PRESS, measured, step, _layout(plate, design_mid_mm=None), T, STEEL) is None


def test_the_calibrated_step_corrects_the_softer_plate_end_to_end(plate):
    """One real solve: the loop's step brings the true (softer) plate closer to the design than it was."""
    step = StepStrokes(np.asarray(plate.planned.upper_mm), np.asarray(plate.planned.lower_mm), plate.active)
    correction = calibrated_step(PRESS, [(step.upper_mm, step.lower_mm, plate.measured)], step, _layout(plate), T,
                                 STEEL)
    assert correction is not None and "effective yield stress" in correction.notes[0]
    after = deviation(PRESS, predict_mid_heights(PRESS, correction.upper_mm, correction.lower_mm, plate.active,
                                                 plate.outline, T, plate.true), plate.target, plate.active)
    assert np.nanmax(np.abs(after)) < 0.5 * np.nanmax(np.abs(plate.measured))
