"""Deviations at the punches: measured near the axes, filled across scan gaps, under the trim margin (mppf.measure.punches)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

import margin_helpers as mh
import scan_helpers as sh
from mppf.core.transform import rotation_angle_deg
from mppf.measure.compare import compare
from mppf.measure.options import CompareOptions


def _punch_grid():
    """Punch axes every 120 mm in x and 80 mm in y; the outer ring lies in the band, the next one beyond it."""
    px, py = np.meshgrid(np.arange(-1680.0, 1681.0, 120.0), np.arange(-1120.0, 1121.0, 80.0))
    return px, py


def test_punch_deviations_with_gaps_interpolated():
    formed_and_scan = sh.formed_and_scan()
    press = sh.press()
    formed, sample, c = formed_and_scan
    px, py = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    on_plate = (np.abs(px) < 1500) & (np.abs(py) < 1000)
    assert c.punch_deviation_mm.shape == press.shape
    assert np.all(np.isfinite(c.punch_deviation_mm[on_plate]))
    assert np.all(np.isnan(c.punch_deviation_mm[(np.abs(px) > 1600) | (np.abs(py) > 1100)]))
    assert np.nanmax(np.abs(c.punch_deviation_mm)) < 1.0
    # the occlusion blobs hide some punches: those are interpolated, the rest measured
    hidden = sample.hidden_xy_mm
    dist, _ = cKDTree(hidden).query(np.column_stack([px[on_plate], py[on_plate]]))
    deep_inside = np.zeros(press.shape, bool)
    deep_inside[on_plate] = dist < 5.0
    assert c.punch_interpolated.any()
    assert not c.punch_interpolated[~on_plate].any()
    assert c.punch_interpolated[deep_inside].mean() > 0.5


def test_punches_under_the_margin_get_deviations():
    _, _, scan = mh.scan(n=25000, seed=8)  # about 14 points within the default radius (36 mm) of a punch
    px, py = _punch_grid()
    grid = np.stack([px, py], axis=-1)
    in_band = ((np.abs(px) == 1560.0) & (np.abs(py) <= 1040.0)) | ((np.abs(py) == 1040.0) & (np.abs(px) <= 1560.0))
    beyond = (np.abs(px) > 1600.0) | (np.abs(py) > 1100.0)
    net = ~in_band & ~beyond
    assert in_band.sum() == 2 * 27 + 2 * 25
    c = compare(mh.design(), scan, CompareOptions(margin_mm=mh.MARGIN_MM, tf_press_design=np.eye(4), punch_xy_mm=grid))
    assert "outline fit (from above the press): turned" in c.notes[0]  # the outline fit ran against the grown outline
    error = c.transform @ mh.pose()
    assert rotation_angle_deg(error) < 0.05
    assert np.linalg.norm(error[:3, 3]) < 5.0
    assert np.all(np.isfinite(c.punch_deviation_mm[in_band]))
    assert np.all(np.isfinite(c.punch_deviation_mm[net]))
    assert np.all(np.isnan(c.punch_deviation_mm[beyond]))
    assert not c.punch_interpolated.any()  # measured there, not filled in
    assert np.max(np.abs(c.punch_deviation_mm[net])) < 0.3
    assert np.max(np.abs(c.punch_deviation_mm[in_band])) < 1.0
    # without the margin those punches are off the plate
    plain = compare(mh.design(), scan, CompareOptions(tf_press_design=np.eye(4), punch_xy_mm=grid))
    assert np.all(np.isnan(plain.punch_deviation_mm[in_band]))
