"""Per-point export of a comparison: PLY scalar fields and CSV columns (mppf.report.export)."""

from __future__ import annotations

import numpy as np
import pytest
from plyfile import PlyData

import scan_helpers as sh
from mppf.core.errors import InputError
from mppf.report.export import export_points


def test_ply_holds_every_point_with_scalar_fields(tmp_path):
    _, _, c = sh.bump_result()
    path = export_points(c, tmp_path / "points.ply")
    ply = PlyData.read(str(path))
    assert not ply.text  # binary
    vertex = ply["vertex"]
    names = [p.name for p in vertex.properties]
    assert names[:3] == ["x", "y", "z"]
    assert {"scalar_deviation", "scalar_form_deviation", "scalar_inlier", "scalar_set_aside", "scalar_outside",
            "scalar_margin"} <= set(names)
    assert vertex.count == c.n_points
    xyz = np.column_stack([vertex["x"], vertex["y"], vertex["z"]])
    assert np.allclose(xyz, c.measured_in_design)
    assert np.allclose(vertex["scalar_deviation"], c.deviation_mm, equal_nan=True)
    assert np.allclose(vertex["scalar_form_deviation"], c.form_deviation_mm, equal_nan=True)
    assert (vertex["scalar_inlier"] == c.inlier).all() and (vertex["scalar_set_aside"] == c.is_outlier).all()


def test_csv_columns_and_bad_suffix(tmp_path):
    _, _, c = sh.bump_result()
    path = export_points(c, tmp_path / "points.csv")
    header = path.read_text().splitlines()[0].split(",")
    assert header[:5] == ["x_mm", "y_mm", "z_mm", "deviation_mm", "form_deviation_mm"]
    table = np.genfromtxt(path, delimiter=",", skip_header=1)
    assert table.shape == (c.n_points, 9)
    assert np.allclose(table[:, 3], c.deviation_mm, atol=1e-4)
    assert table[:, 5].sum() == c.n_inliers
    with pytest.raises(InputError, match=".ply"):
        export_points(c, tmp_path / "points.xyz")
