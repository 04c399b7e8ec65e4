"""The design skin and the deviations of a scan: normal sign, outside and trim-margin masks (mppf.measure.deviations)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import margin_helpers as mh
import scan_helpers as sh
from mppf.core.transform import make_tf
from mppf.measure.compare import compare
from mppf.measure.options import CompareOptions


def test_design_normal_up_in_the_press_decides_the_sign():
    bump_result = sh.bump_result()
    u, v, measured = sh.measured(n=5000, seed=2)
    # the design lies upside down in the press: "above" is now the frame's -n side
    flip = make_tf(Rotation.from_euler("x", 180, degrees=True).as_matrix())
    c = compare(sh.design(), measured, CompareOptions(tf_press_design=flip))
    assert c.normal_sign == -1.0
    shape = sh.bump(u, v) / 5.0
    near = shape > 0.6
    amplitude = np.sum(c.deviation_mm[near] * shape[near]) / np.sum(shape[near] ** 2)
    assert amplitude == pytest.approx(-5.0, abs=0.3)
    _, _, upright = bump_result
    assert upright.normal_sign == 1.0


def test_without_the_margin_the_band_is_outside():
    """The same gross scan compared as if it were net: the band is not in the margin."""
    u, v, scan = mh.scan()
    c = compare(mh.design(), scan, CompareOptions(margin_mm=0.0))
    assert not c.in_margin.any()
    far = (np.abs(u) > mh.HALF_U + 70.0) | (np.abs(v) > mh.HALF_V + 70.0)  # beyond 1.5 design spacings
    assert c.is_outside[far].mean() > 0.95


def test_a_bump_in_the_margin_leaves_the_net_statistics_alone():
    runs = mh.runs()
    u, v, scan = mh.scan(with_bump=True)
    c = compare(mh.design(), scan, CompareOptions(margin_mm=mh.MARGIN_MM))
    ref = runs["gross"]
    assert c.rms_mm == pytest.approx(ref.rms_mm, abs=0.005)
    assert c.max_abs_mm == pytest.approx(ref.max_abs_mm, abs=0.05)
    assert c.form_max_abs_mm == pytest.approx(ref.form_max_abs_mm, abs=0.05)
    assert c.form_max_abs_mm < 0.6  # a 6 mm bump in the statistics would be seen
    # the bump is measured (in the margin) but not in the statistics
    top = mh.bump(u, v) > 5.0
    assert top.sum() >= 5
    assert c.in_margin[top].all() and not c.inlier[top].any()
    assert np.median(c.deviation_mm[top]) == pytest.approx(6.0, abs=0.8)
