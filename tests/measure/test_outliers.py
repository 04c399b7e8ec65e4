"""Outliers and the form deviation of a comparison (mppf.measure.outliers)."""

from __future__ import annotations

import numpy as np
import pytest

import scan_helpers as sh
from mppf.core.transform import rotation_angle_deg
from mppf.measure.compare import compare
from mppf.measure.options import CompareOptions


def test_form_deviation_averages_out_the_scanner_noise():
    """The plate's form deviation keeps the 5 mm bump but not the 0.3 mm point noise."""
    u, v, c = sh.bump_result()
    form = c.form_deviation_mm
    assert np.isnan(form[~c.inlier]).all() and np.isfinite(form[c.inlier]).all()
    # the form max is the largest form value, or a little more where the extreme lies between points
    assert np.max(np.abs(form[c.inlier])) <= c.form_max_abs_mm <= np.max(np.abs(form[c.inlier])) + 0.1
    # the bump's peak survives the local planes (150 mm wide bump, planes over ~12 points)
    assert c.form_max_abs_mm == pytest.approx(5.0, abs=0.2)
    # away from the bump the form deviation is the noise averaged over about 12 points
    far = sh.bump(u, v) < 5e-3
    raw_spread = np.std(c.deviation_mm[far & c.inlier])
    form_spread = np.std(form[far & c.inlier])
    assert raw_spread == pytest.approx(0.3, abs=0.05)
    assert form_spread < 0.5 * raw_spread
    doc = c.to_dict()
    assert doc["form_max_abs_mm"] == pytest.approx(c.form_max_abs_mm)
    assert doc["in_tolerance"] is False


def test_noise_alone_never_fails_the_tolerance_but_its_raw_extremes_would():
    """1.0 mm of scanner noise puts single points beyond a 2.5 mm tolerance; the form
    deviation of that perfectly formed plate stays well inside it."""
    _, _, measured = sh.measured(n=8000, with_bump=False, noise_mm=1.0, seed=6)
    c = compare(sh.design(), measured, CompareOptions(tolerance_mm=2.5,
            rms_tolerance_mm=1.5))  # 1 mm noise: RMS about 1 mm
    assert c.max_abs_mm > 2.5  # raw points: noise extremes
    assert c.form_max_abs_mm < 2.0  # about 1.6: the local planes cut the noise by about 2.5x
    assert c.in_tolerance
    assert rotation_angle_deg(c.transform @ sh.pose()) < 0.1


def test_occluded_scan_with_outliers_still_registers():
    formed, sample, c = sh.formed_and_scan()
    error = c.transform @ sample.tf_scan_press  # press -> design (= press here): identity
    assert rotation_angle_deg(error) < 0.05
    assert np.linalg.norm(error[:3, 3]) < 10.0
    assert c.rms_mm == pytest.approx(0.3, abs=0.05)
    # the plate is within its limits, but artefacts 5-50 mm off were set aside: a person looks at them
    assert c.form_max_abs_mm <= c.tolerance_mm and c.rms_mm <= c.rms_tolerance_mm
    assert c.verdict.kind == "needs_review" and not c.in_tolerance
    assert c.set_aside.count == int(c.is_outlier.sum()) and c.set_aside.beyond_tolerance > 0
    assert c.set_aside.worst_punch.startswith("row ")
    # outliers found: nearly all true ones, almost no false ones
    true = sample.is_outlier
    assert (c.is_outlier & true).sum() >= 0.95 * true.sum()
    assert (c.is_outlier & ~true).sum() <= 0.005 * len(true)
    assert c.to_dict()["n_outliers"] == int(c.is_outlier.sum())


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_spike_is_set_aside_also_beside_another_spike(seed):
    """3 % of the points of a dense scan thrown 5-50 mm off (many have another spike among their neighbours, some
    at the rim of the neighbourhood, where a quadric fitted to all neighbours bends onto it): every one is set aside,
    no other point."""
    from mppf.measure.outliers import find_outliers

    rng = np.random.default_rng(seed)
    spacing_mm = 20.0
    u, v = np.meshgrid(np.arange(-1500.0, 1500.1, spacing_mm), np.arange(-1000.0, 1000.1, spacing_mm))
    uv = np.column_stack([u.ravel(), v.ravel()]) + rng.uniform(-0.5, 0.5, (u.size, 2)) * spacing_mm
    deviation = 1e-3 * uv[:, 0] + 2e-7 * uv[:, 1] ** 2 + rng.normal(0.0, 0.3, len(uv))  # a smooth error field
    spikes = rng.choice(len(uv), int(0.03 * len(uv)), replace=False)
    deviation[spikes] += rng.uniform(5.0, 50.0, spikes.size) * rng.choice([-1.0, 1.0], spikes.size)
    truth = np.zeros(len(uv), dtype=bool)
    truth[spikes] = True
    found = find_outliers(uv, deviation, np.ones(len(uv), dtype=bool)).mask
    assert np.array_equal(found, truth), (f"{int((truth & ~found).sum())} spikes kept, "
                                          f"{int((found & ~truth).sum())} plain points set aside")
