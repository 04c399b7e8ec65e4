"""Compare end to end: a scan registered onto its design, its deviations and statistics (mppf.measure.compare)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import margin_helpers as mh
import scan_helpers as sh
from mppf.core.errors import GeometryError, InputError
from mppf.core.transform import rotation_angle_deg
from mppf.geometry.read import read_points
from mppf.measure.compare import compare
from mppf.measure.options import CompareOptions


def test_compare_recovers_a_5_mm_bump():
    u, v, c = sh.bump_result()
    shape = sh.bump(u, v) / 5.0
    near = shape > 0.6
    # amplitude of the bump by least squares on its known shape (about 60 points)
    amplitude = np.sum(c.deviation_mm[near] * shape[near]) / np.sum(shape[near] ** 2)
    assert amplitude == pytest.approx(5.0, abs=0.2)
    # and the plain median of the points within 20 mm of its centre
    centre = np.hypot(u - sh.BUMP_UV[0], v - sh.BUMP_UV[1]) < 20.0
    assert np.median(c.deviation_mm[centre]) == pytest.approx(5.0, abs=0.4)
    far = shape < 1e-3
    assert abs(np.median(c.deviation_mm[far])) < 0.1
    assert np.percentile(np.abs(c.deviation_mm[far]), 95) < 0.8
    # the bump is a shape error, not outliers; it puts the largest deviation near 5 mm
    assert not c.is_outlier[near].any()
    assert c.max_abs_mm == pytest.approx(5.0, abs=1.3)
    assert c.max_abs_mm > c.tolerance_mm and not c.in_tolerance
    # the registration found the pose (measured -> design undoes the scan pose)
    assert rotation_angle_deg(c.transform @ sh.pose()) < 0.05
    assert np.linalg.norm((c.transform @ sh.pose())[:3, 3]) < 10.0


def test_perfect_scan_gives_the_noise_as_rms():
    _, _, measured = sh.measured(n=5000, with_bump=False, noise_mm=0.3, seed=4)
    c = compare(sh.design(), measured)
    # the normal component of isotropic noise of 0.3 mm per axis
    assert c.rms_mm == pytest.approx(0.3, abs=0.03)
    assert abs(c.mean_mm) < 0.03
    assert c.within_tolerance_pct == 100.0
    assert c.in_tolerance
    assert c.is_outlier.sum() < 5


def test_a_different_plate_is_refused(hull_dir):
    design = read_points(hull_dir / "K3_stern_saddle.csv").points
    other = read_points(hull_dir / "K1_midbody_bilge.csv").points  # same size, other shape
    with pytest.raises(GeometryError, match="does not match"):
        compare(design, other)
    # a scan in metres read as millimetres
    with pytest.raises(GeometryError, match="units"):
        compare(design, design / 1000.0)


def test_bad_inputs_are_refused():
    design = sh.design()
    _, _, measured = sh.measured(n=200, with_bump=False)
    with pytest.raises(InputError, match="tolerance"):
        compare(design, measured, CompareOptions(tolerance_mm=0.0))
    with pytest.raises(GeometryError, match="at least"):
        compare(design, measured[:10])
    with pytest.raises(InputError, match="shape"):
        compare(design, measured[:, :2])
    with pytest.raises(InputError, match="tf_press_design"):
        compare(design, measured, CompareOptions(punch_xy_mm=np.zeros((2, 2, 2))))


def test_margin_recovers_the_pose_and_the_net_statistics():
    runs = mh.runs()
    u, v, c, n = runs["u"], runs["v"], runs["gross"], runs["net"]
    error = c.transform @ mh.pose()
    assert rotation_angle_deg(error) < 0.05
    assert np.linalg.norm(error[:3, 3]) < 10.0
    assert np.linalg.norm((n.transform @ mh.pose())[:3, 3]) < 10.0
    # the statistics are those of the net plate: the same as a scan of the net area alone
    assert c.rms_mm == pytest.approx(0.2, abs=0.02)
    assert c.rms_mm == pytest.approx(n.rms_mm, abs=0.01)
    assert c.mean_mm == pytest.approx(n.mean_mm, abs=0.01)
    assert c.form_rms_mm == pytest.approx(n.form_rms_mm, abs=0.01)
    assert c.max_abs_mm < 1.2 and c.form_max_abs_mm < 0.6
    assert c.n_inliers == pytest.approx(n.n_inliers, rel=0.01)
    # the band's points are in the margin: measured, not outside, not in the statistics
    band = mh.band(u, v)
    assert c.in_margin.shape == (u.size,)
    assert c.in_margin.sum() == pytest.approx(band.sum(), rel=0.02)
    assert (c.in_margin == band).mean() > 0.995
    assert not (c.in_margin & c.inlier).any() and not (c.in_margin & c.is_outside).any()
    assert c.is_outside.sum() == 0
    assert c.histogram_counts.sum() == c.n_inliers
    assert c.rms_mm == pytest.approx(np.sqrt(np.mean(c.deviation_mm[c.inlier] ** 2)))
    # the band is measured against the surface's extension: small, finite deviations
    assert np.all(np.isfinite(c.deviation_mm[c.in_margin]))
    assert np.percentile(np.abs(c.deviation_mm[c.in_margin]), 95) < 1.2
    # ... and has form values for maps, kept out of the form statistics
    assert np.isfinite(c.form_deviation_mm[c.in_margin & ~c.is_outlier]).all()
    assert c.form_max_abs_mm == pytest.approx(np.max(np.abs(c.form_deviation_mm[c.inlier])))
    doc = c.to_dict()
    json.dumps(doc)
    assert doc["margin_mm"] == mh.MARGIN_MM and doc["n_margin"] == int(c.in_margin.sum())
    assert any("trim margin" in note for note in c.notes)
    # without a margin nothing changes: no margin points, no note
    assert n.margin_mm == 0.0 and not n.in_margin.any() and n.to_dict()["n_margin"] == 0
    assert not any("trim margin" in note for note in n.notes)


@pytest.mark.parametrize("margin", [-5.0, float("nan"), float("inf"), "wide"])
def test_bad_margin_is_refused(margin):
    _, _, scan = mh.scan(n=500)
    with pytest.raises(InputError, match="trim margin") as info:
        compare(mh.design(), scan, CompareOptions(margin_mm=margin))
    assert info.value.hint
