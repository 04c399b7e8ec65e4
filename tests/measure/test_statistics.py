"""Statistics and histogram of a comparison (mppf.measure.statistics)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import scan_helpers as sh


def test_statistics_and_histogram_are_consistent():
    _, _, c = sh.bump_result()
    d = c.deviation_mm[c.inlier]
    assert c.rms_mm == pytest.approx(np.sqrt(np.mean(d**2)))
    assert c.max_abs_mm == pytest.approx(np.max(np.abs(d)))
    assert c.mean_mm == pytest.approx(np.mean(d))
    assert c.within_tolerance_pct == pytest.approx(100.0 * np.mean(np.abs(d) <= 2.5))
    assert 90.0 < c.within_tolerance_pct < 100.0
    assert c.histogram_counts.sum() == c.n_inliers
    assert len(c.histogram_edges_mm) == len(c.histogram_counts) + 1
    assert c.histogram_edges_mm[0] <= -c.max_abs_mm and c.histogram_edges_mm[-1] >= c.max_abs_mm
    doc = c.to_dict()
    json.dumps(doc)
    for key in ("rms_mm", "max_abs_mm", "within_tolerance_pct", "transform", "histogram", "registration"):
        assert key in doc
    assert np.allclose(np.array(doc["transform"]), c.transform)
