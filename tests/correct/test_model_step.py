"""The springback-model step: each curvature component divided by its springback slope, in a trust region."""

from __future__ import annotations

import numpy as np

from mppf.correct.compensate import CompensateOptions, compensate
from mppf.correct.model_step import MAX_STEP_RATIO, MIN_SLOPE, model_correction, springback_slopes
from mppf.model.material import Material
from plan_helpers import grid, press  # noqa: F401 (fixtures)

THICKNESS_MM = 20.0


def test_model_correction_divides_each_curvature_component_by_its_springback_slope(press, grid):
    """A bend along x (loaded R 4 m): a curvature error along x is corrected by 1/f'(k),
    a twist error by 1/((f(k1) - f(k2)) / (k1 - k2)), which is larger; a rigid offset not at all."""
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
    # through compensate: the model's step, held to the limits
    c = compensate(upper, lower, np.where(active, a * px**2 / 2, np.nan), press=press, thickness_mm=THICKNESS_MM,
                   material=steel, options=CompensateOptions(smoothing=0.0))
    assert any("springback-model" in n for n in c.notes)
    assert np.allclose((c.upper_mm - c.lower_mm)[active], THICKNESS_MM)
    assert np.abs(np.diff(c.applied_mm[active.any(axis=1)][:, active.any(axis=0)], axis=1)).max() \
        <= press.max_neighbour_diff_mm + 1e-6


def test_model_step_is_scaled_into_its_trust_region(press, grid):
    """A twist error needs about 3x its size in strokes; the trust region allows 2.5x the largest error."""
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
