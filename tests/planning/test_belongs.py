"""Does the flat belong to the design: neighbour strain of paired points, areas of unpaired ones."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import GeometryError
from mppf.planning.belongs import MAX_AREA_MISMATCH_PCT, check_flat_belongs, neighbour_strain_pct
from plan_helpers import cylinder_points, developed_cylinder

RADIUS = 3000.0


def test_the_unfolding_keeps_neighbour_distances_and_a_stretched_flat_does_not():
    design = cylinder_points(RADIUS, 2800.0, 1500.0)
    flat = developed_cylinder(RADIUS, 2800.0, 1500.0)
    assert np.percentile(np.abs(neighbour_strain_pct(design, flat)), 95) < 0.05
    report = check_flat_belongs(design, flat, True, 2800.0 * 1500.0)
    assert report["paired"] and report["neighbour_strain_p95_pct"] < 0.05
    stretched = flat * [1.03, 1.0, 1.0]  # 3 % longer along x
    strain = neighbour_strain_pct(design, stretched)
    assert np.percentile(np.abs(strain), 95) == pytest.approx(100 * (1 / 1.03 - 1) * -1, rel=0.05)
    with pytest.raises(GeometryError, match="does not belong.*95th percentile"):
        check_flat_belongs(design, stretched, True, 2800.0 * 1500.0)


def test_an_unpaired_flat_is_judged_by_its_area():
    flat = developed_cylinder(RADIUS, 2800.0, 1500.0, n_u=37, n_v=27)
    area_mm2 = 2800.0 * 2 * RADIUS * np.arcsin(750.0 / RADIUS)  # the developed width
    report = check_flat_belongs(None, flat, False, area_mm2)
    assert abs(report["area_mismatch_pct"]) < 0.01 and "neighbour_strain_p95_pct" not in report
    with pytest.raises(GeometryError, match=f"allowed {MAX_AREA_MISMATCH_PCT}"):
        check_flat_belongs(None, flat, False, area_mm2 * 1.05)
