"""Coverage-aware verdicts (issue 20.4, mppf.measure.coverage): what was not measured is named, and never passed."""

from __future__ import annotations

import numpy as np
import pytest

import scan_helpers as sh
from mppf.core.errors import InputError
from mppf.core.transform import apply_tf
from mppf.measure.compare import compare
from mppf.measure.options import CompareOptions
from mppf.measure.coverage import GAP_MM, MAX_GAP_MM, allowed_gap_mm, coverage

DENT_UV = np.array([400.0, 200.0])


def _scan(keep, n=12000, dent_mm=0.0, seed=3):
    """A dense random scan of the analytic plate (0.3 mm noise, a dent at DENT_UV), the points ``keep(u, v)`` only."""
    rng = np.random.default_rng(seed)
    u, v = rng.uniform(-1500, 1500, n), rng.uniform(-1000, 1000, n)
    sink = dent_mm * np.exp(-((u - DENT_UV[0]) ** 2 + (v - DENT_UV[1]) ** 2) / (2 * 80.0**2))
    pts = np.column_stack([u, v, sh.height(u, v)]) - sink[:, None] * sh.normals(u, v)
    pts += rng.normal(0.0, 0.3, pts.shape)
    return apply_tf(sh.pose(), pts[keep(u, v)])


def _grid(spacing_mm, keep=lambda u, v: np.ones(u.shape, dtype=bool)):
    u, v = np.meshgrid(np.arange(-1500, 1500.1, spacing_mm), np.arange(-1000, 1000.1, spacing_mm))
    u, v = u.ravel(), v.ravel()
    pts = np.column_stack([u, v, sh.height(u, v)]) + np.random.default_rng(0).normal(0.0, 0.05, (u.size, 3))
    return apply_tf(sh.pose(), pts[keep(u, v)])


def test_an_occluded_worst_region_needs_review_and_is_named():
    """A 4 mm dent hidden by an occlusion: the measured part is in tolerance, the verdict is not."""
    hidden = lambda u, v: np.hypot(u - DENT_UV[0], v - DENT_UV[1]) > 250.0
    c = compare(sh.design(), _scan(hidden, dent_mm=4.0), CompareOptions(tolerance_mm=2.5))
    assert c.form_max_abs_mm <= 2.5 and c.rms_mm <= 1.0  # what was measured is fine
    assert c.verdict.kind == "needs_review" and not c.in_tolerance
    (gap,) = c.coverage.regions
    assert np.linalg.norm(np.asarray(gap.centroid_uv_mm) - DENT_UV) < 30.0
    assert gap.gap_mm == pytest.approx(500.0, abs=40.0) and not gap.on_rim
    assert gap.area_mm2 == pytest.approx(np.pi * 250.0**2, rel=0.15)
    assert "not measured" in c.headline and gap.describe() in c.headline
    doc = c.to_dict()["coverage"]
    assert doc["n_regions"] == 1 and not doc["complete"] and doc["regions"][0]["gap_mm"] == gap.gap_mm
    assert c.to_dict()["verdict"]["uncovered_regions"] == 1
    # measured, the same dent fails the tolerance: the hidden area could have held the worst spot
    assert compare(sh.design(), _scan(lambda u, v: u > -1e9, dent_mm=4.0)).verdict.kind == "out_of_tolerance"


def test_a_rim_band_without_points_needs_review_a_narrow_one_does_not():
    # a 300 mm band along the v = 1000 edge without points (the free best fit slides some of the way into it)
    c = compare(sh.design(), _scan(lambda u, v: v < 1000.0 - 300.0), CompareOptions(tolerance_mm=2.5))
    assert c.verdict.kind == "needs_review"
    gap = c.coverage.regions[0]  # the largest first
    assert gap.on_rim and c.coverage.allowed_gap_mm < gap.gap_mm <= 300.0 + 25.0
    assert gap.box_uv_mm[2] - gap.box_uv_mm[0] > 2500.0 and gap.box_uv_mm[1] > 600.0  # along the edge
    assert "on the rim" in c.headline
    # a band narrower than the allowed gap (100 mm) is the scanner's rim: not flagged
    c = compare(sh.design(), _scan(lambda u, v: v < 1000.0 - 40.0), CompareOptions(tolerance_mm=2.5))
    assert c.coverage.complete and c.verdict.kind == "in_tolerance"
    assert "the whole net plate measured" in c.headline


@pytest.mark.parametrize("spacing_mm", [50.0, 141.0])
def test_a_sparse_grid_on_a_smooth_plate_stays_in_tolerance_a_missing_block_does_not(spacing_mm):
    """A few hundred points on a grid: the gaps between them are the measurement's own, not holes."""
    c = compare(sh.design(), _grid(spacing_mm))
    assert c.verdict.kind == "in_tolerance" and c.coverage.complete
    assert c.coverage.largest_gap_mm < c.coverage.allowed_gap_mm
    assert c.coverage.allowed_gap_mm == pytest.approx(allowed_gap_mm(c.coverage.spacing_mm))
    # points not measured over a disc of 350 mm radius: a gap no spacing explains
    c = compare(sh.design(), _grid(spacing_mm, lambda u, v: np.hypot(u + 600.0, v - 100.0) > 350.0))
    assert c.verdict.kind == "needs_review" and len(c.coverage.regions) == 1
    assert np.linalg.norm(np.asarray(c.coverage.regions[0].centroid_uv_mm) - [-600.0, 100.0]) < spacing_mm


def test_a_grid_coarser_than_the_largest_allowed_gap_is_never_passed():
    c = compare(sh.design(), _grid(300.0))
    assert c.verdict.kind == "needs_review" and c.coverage.allowed_gap_mm == MAX_GAP_MM
    assert c.coverage.uncovered_pct > 50.0


def test_the_allowed_gap_follows_the_spacing_between_its_bounds():
    assert allowed_gap_mm(5.0) == GAP_MM  # a dense scan: the smallest allowed gap
    assert allowed_gap_mm(40.0) == pytest.approx(200.0)  # 5 spacings
    assert allowed_gap_mm(200.0) == MAX_GAP_MM  # never wider than the largest
    assert allowed_gap_mm(float("nan")) == GAP_MM


def test_coverage_of_a_regular_grid_with_a_hole_and_its_press_place():
    from scipy.spatial import cKDTree

    u, v = np.meshgrid(np.arange(0.0, 2000.1, 20.0), np.arange(0.0, 1000.1, 20.0))
    pts = np.column_stack([u.ravel(), v.ravel()])
    pts = pts[np.hypot(pts[:, 0] - 1000.0, pts[:, 1] - 500.0) > 200.0]
    tree = cKDTree(pts)
    outline = np.array([[0.0, 0.0], [2000.0, 0.0], [2000.0, 1000.0], [0.0, 1000.0]])
    cov = coverage(outline, lambda cells: tree.query(cells)[0], 20.0,
                   where=lambda uv: (uv + 10.0, "row 1, col 1"))
    (gap,) = cov.regions
    assert gap.gap_mm == pytest.approx(400.0, abs=2 * 12.5) and gap.punch == "row 1, col 1"
    assert np.allclose(gap.press_xy_mm, np.asarray(gap.centroid_uv_mm) + 10.0)
    assert "near punch row 1, col 1" in cov.describe()
    with pytest.raises(InputError, match="gap"):
        coverage(outline, lambda cells: tree.query(cells)[0], 20.0, gap_mm=0.0)
    with pytest.raises(InputError, match="largest allowed gap"):
        compare(sh.design(), _grid(100.0), CompareOptions(gap_mm=200.0, max_gap_mm=150.0))


def test_the_deviation_map_draws_the_areas_not_measured(tmp_path):
    from mppf.report.deviation import deviation_map_figure

    c = compare(sh.design(), _scan(lambda u, v: v < 1000.0 - 300.0))
    fig = deviation_map_figure(c)
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert any(label.startswith(f"not measured: {len(c.coverage.regions)} area(s)") for label in labels)
    fig.savefig(tmp_path / "map.png")
