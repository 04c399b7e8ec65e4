"""Stroke compensation: sign convention, secant gain, dimpling and stroke limits."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.correct.compensate import GAIN_RANGE, PreviousCycle, compensate, limit_correction
from mppf.core.errors import InputError
from mppf.planning.press import example_press_path, load_press

THICKNESS_MM = 20.0


@pytest.fixture(scope="module")
def press():
    return load_press(example_press_path())


@pytest.fixture(scope="module")
def grid(press):
    px, py = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    active = (np.abs(px) <= 1500) & (np.abs(py) <= 1000)
    lower = np.where(active, px**2 / 8000.0 - 30.0, np.nan)
    return px, py, active, lower


def test_positive_error_lowers_both_matrices_by_gain_times_error(press, grid):
    px, py, active, lower = grid
    upper = lower + THICKNESS_MM
    error = np.where(active, 2.0, np.nan)  # the plate lies 2 mm above the design everywhere
    corr = compensate(upper, lower, error, press=press, thickness_mm=THICKNESS_MM, gain=1.5)
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
    corr = compensate(lower + THICKNESS_MM, lower, error, press=press, thickness_mm=THICKNESS_MM, smoothing=0.0)
    assert np.all(corr.applied_mm[active & (px > 0)] == 0.0)
    assert np.allclose(corr.applied_mm[active & (px < 0)], -1.0)


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
        corr = compensate(lower + THICKNESS_MM, lower, error, press=press, thickness_mm=THICKNESS_MM,
                          previous=previous)
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
                      previous=PreviousCycle(lower_mm=h0, punch_error_mm=0.7 * (h0 - target)), smoothing=0.0)
    assert np.allclose(corr.gain[active], 1 / 0.7)
    assert np.allclose(corr.lower_mm[active], target[active])


def test_secant_falls_back_and_clips(press, grid):
    px, py, active, lower = grid
    error = np.where(active, 1.0, np.nan)
    # no stroke change since the last cycle: the secant is undefined, the default gain is used
    corr = compensate(lower + THICKNESS_MM, lower, error, press=press, thickness_mm=THICKNESS_MM, gain=1.2,
                      previous={"lower_mm": lower, "punch_error_mm": error + 0.5})
    assert np.allclose(corr.gain[active], 1.2)
    # a huge apparent gain is clipped to the range
    corr = compensate(lower + THICKNESS_MM, lower, error, press=press, thickness_mm=THICKNESS_MM,
                      previous=PreviousCycle(lower_mm=lower - 10.0, punch_error_mm=error - 0.2))
    assert np.allclose(corr.gain[active], GAIN_RANGE[1])
    # a wrong-signed secant (the plate moved against the punch) falls back to the default
    corr = compensate(lower + THICKNESS_MM, lower, error, press=press, thickness_mm=THICKNESS_MM,
                      previous=PreviousCycle(lower_mm=lower - 1.0, punch_error_mm=error + 1.0))
    assert np.allclose(corr.gain[active], 1.0)


def _neighbour_diffs(values, active):
    out = []
    for axis in (0, 1):
        a = np.moveaxis(values, axis, 0)
        m = np.moveaxis(active, axis, 0)
        both = m[1:] & m[:-1]
        out.append(np.abs(a[1:] - a[:-1])[both])
    return np.concatenate(out)


def test_corrections_respect_the_dimpling_limit(press, grid):
    px, py, active, lower = grid
    error = np.where(active, 0.0, np.nan)
    spike = np.argwhere(active)[len(np.argwhere(active)) // 2]
    error[tuple(spike)] = 100.0  # one punch wildly off
    corr = compensate(lower + THICKNESS_MM, lower, error, press=press, thickness_mm=THICKNESS_MM, gain=1.0)
    diffs = _neighbour_diffs(corr.applied_mm, active)
    assert diffs.max() <= press.max_neighbour_diff_mm + 1e-6
    assert corr.applied_mm[tuple(spike)] < -press.max_neighbour_diff_mm * 0.5  # still corrected, less
    assert corr.clipped[tuple(spike)]
    assert any("limited" in note for note in corr.notes)


def test_corrections_respect_the_stroke_limits(press, grid):
    px, py, active, _ = grid
    lower = np.where(active, press.lower.max_mm - 2.0, np.nan)  # lower tips near their top
    upper = np.where(active, press.upper.min_mm + 3.0, np.nan)  # (an odd gap, only to test limits)
    error = np.where(active, -10.0, np.nan)  # wants to raise by 10 mm
    corr = compensate(upper, lower, error, press=press, thickness_mm=THICKNESS_MM)
    assert np.all(corr.lower_mm[active] <= press.lower.max_mm + 1e-9)
    assert np.allclose(corr.applied_mm[active], 2.0)
    assert corr.clipped[active].all()
    error = np.where(active, 10.0, np.nan)  # wants to lower by 10 mm: the upper matrix stops it
    corr = compensate(upper, lower, error, press=press, thickness_mm=THICKNESS_MM)
    assert np.all(corr.upper_mm[active] >= press.upper.min_mm - 1e-9)
    assert np.allclose(corr.applied_mm[active], -3.0)


def test_bad_inputs_are_refused(press, grid):
    px, py, active, lower = grid
    with pytest.raises(InputError, match="shape"):
        compensate(lower[:, :3], lower, lower, press=press, thickness_mm=20.0)
    with pytest.raises(InputError, match="gain"):
        compensate(lower, lower, lower, press=press, thickness_mm=20.0, gain=0.0)
    with pytest.raises(InputError, match="previous"):
        compensate(lower, lower, lower, press=press, thickness_mm=20.0, previous={"lower_mm": lower})


def test_model_correction_divides_each_curvature_component_by_its_springback_slope(press, grid):
    """A bend along x (loaded R 4 m): a curvature error along x is corrected by 1/f'(k),
    a twist error by 1/((f(k1) - f(k2)) / (k1 - k2)), which is larger; a rigid offset not at all."""
    from mppf.correct.compensate import MIN_SLOPE, model_correction, springback_slopes
    from mppf.forming.material import Material

    px, py, active, lower = grid
    upper = lower + THICKNESS_MM
    steel = Material()
    d1, d2, twist = springback_slopes(np.array(1.0 / 4000.0), np.array(0.0), THICKNESS_MM, steel)
    assert 0.2 < twist < d1 < 1.0 and d2 == 0.0  # ratio R_i/R_f 0.34 against the slope 0.89
    inner = active & (np.abs(px) <= 1000) & (np.abs(py) <= 600)
    hx, hy = press.pitch_x_mm, press.pitch_y_mm
    # curvature error along the bend: e = a x^2 / 2
    a = 2e-6
    corr = model_correction(upper, lower, np.where(active, a * px**2 / 2, np.nan), press=press,
                            thickness_mm=THICKNESS_MM, material=steel)
    cxx = np.gradient(np.gradient(corr, hx, axis=1), hx, axis=1)
    assert np.allclose(cxx[inner], -a / d1, rtol=0.05)
    # twist error: e = b x y
    b = 1e-6
    corr = model_correction(upper, lower, np.where(active, b * px * py, np.nan), press=press,
                            thickness_mm=THICKNESS_MM, material=steel)
    cxy = np.gradient(np.gradient(corr, hy, axis=0), hx, axis=1)
    assert np.allclose(cxy[inner], -b / max(float(twist), MIN_SLOPE), rtol=0.15)  # damped at MIN_SLOPE
    assert np.abs(cxy[inner]).min() > 2.0 * b  # the twist needs more than twice the error
    # a rigid offset is the comparison's business: no correction
    corr = model_correction(upper, lower, np.where(active, 2.0, np.nan), press=press, thickness_mm=THICKNESS_MM,
                            material=steel)
    assert np.abs(corr[active]).max() < 1e-6 and np.all(corr[~active] == 0)
    # through compensate: the model replaces -lambda e, the limits still apply
    c = compensate(upper, lower, np.where(active, a * px**2 / 2, np.nan), press=press, thickness_mm=THICKNESS_MM,
                   material=steel, smoothing=0.0)
    assert any("springback-model" in n for n in c.notes)
    assert np.allclose((c.upper_mm - c.lower_mm)[active], THICKNESS_MM)
    assert np.abs(np.diff(c.applied_mm[active.any(axis=1)][:, active.any(axis=0)], axis=1)).max() \
        <= press.max_neighbour_diff_mm + 1e-6


def test_model_step_is_scaled_into_its_trust_region(press, grid):
    """A twist error needs about 3x its size in strokes; the trust region allows 2.5x the largest error."""
    from mppf.correct.compensate import MAX_STEP_RATIO
    from mppf.forming.material import Material

    px, py, active, lower = grid
    upper = lower + THICKNESS_MM
    error = np.where(active, 2e-5 * px * py, np.nan)  # a gross twist: tens of mm at the corners
    corr = compensate(upper, lower, error, press=press, thickness_mm=THICKNESS_MM, material=Material())
    applied = corr.applied_mm[active]
    largest_error = np.nanmax(np.abs(error))
    assert np.abs(applied).max() <= MAX_STEP_RATIO * largest_error + 1e-9
    assert np.abs(applied).max() > 0.9 * MAX_STEP_RATIO * largest_error or corr.clipped.any()
    assert any("trust region" in note for note in corr.notes)
    # the step still undoes the error: opposite sign at the corners
    corner = active & (np.abs(px) > 1000) & (np.abs(py) > 600)
    assert np.all(np.sign(applied[corner[active]]) == -np.sign(error[corner]))


def test_limit_correction_holds_any_wanted_change_to_the_press_limits(press, grid):
    """The loop's calibrated correction is held to the same limits as the model step."""
    px, py, active, lower = grid
    wanted = np.where(active, 0.0, np.nan)
    spike = tuple(np.argwhere(active)[len(np.argwhere(active)) // 2])
    wanted[spike] = -60.0  # one punch wildly lower
    applied, clipped = limit_correction(press, lower + THICKNESS_MM, lower, wanted)
    assert _neighbour_diffs(applied, active).max() <= press.max_neighbour_diff_mm + 1e-6
    assert applied[spike] < -0.5 * press.max_neighbour_diff_mm and clipped[spike]
    assert np.all(applied[~active] == 0.0)
    high = np.where(active, 1000.0, np.nan)  # past the lower tips' top
    applied, clipped = limit_correction(press, lower + THICKNESS_MM, lower, high)
    assert np.all((lower + applied)[active] <= press.lower.max_mm + 1e-9) and clipped[active].all()
