"""The report of an unfolding: where on the plate a point lies (mppf.geometry.unfold_report)."""

from __future__ import annotations

import numpy as np

from mppf.geometry.unfold_report import region_name


def test_region_names():
    uv = np.array([[0.0, 0.0], [3000.0, 0.0], [3000.0, 2000.0], [0.0, 2000.0], [1500.0, 1000.0]])
    assert region_name(uv, 2) == "the +u/+v corner"
    assert region_name(uv, 0) == "the -u/-v corner"
    assert region_name(uv, 4) == "the middle"
    assert region_name(np.vstack([uv, [[2900.0, 1000.0]]]), 5) == "the +u edge"
    assert region_name(np.vstack([uv, [[3000.0, 1400.0]]]), 5) == "the +u edge"  # 70 % up: not a corner
    assert region_name(np.vstack([uv, [[100.0, 1600.0]]]), 5) == "the -u/+v corner"
