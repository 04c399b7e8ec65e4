"""Set-aside points beyond the tolerance cleared by another scan of the same spot (issue 13 with rescans).

Two scans of one plate in one frame, their spikes at different places: each scan's spikes are
re-measured within the tolerance by the other, the union is in tolerance with the cleared points
counted; a narrow dent present in both scans is never passed; one scan with spikes still needs review.
"""

from __future__ import annotations

import numpy as np
import pytest

from mppf.measure.compare import compare
from mppf.measure.options import CompareOptions

TOLERANCE_MM = 2.5
SPACING_MM = 20.0


def _shape(x, y):
    return x**2 / (2 * 8000.0) + y**2 / (2 * 15000.0)


@pytest.fixture(scope="module")
def design():
    x, y = np.meshgrid(np.linspace(-500.0, 500.0, 41), np.linspace(-300.0, 300.0, 25))
    return np.column_stack([x.ravel(), y.ravel(), _shape(x, y).ravel()])


def _scan(seed, spikes=0.01, dent_mm=0.0, sigma_mm=8.0):
    """A jittered 20 mm grid over the plate, 0.3 mm noise, ``spikes`` of the points 5 - 50 mm off; a narrow dent
    (``sigma_mm``, ``dent_mm`` deep) at (150, 60)."""
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.arange(-490.0, 491.0, SPACING_MM), np.arange(-290.0, 291.0, SPACING_MM))
    xy = np.column_stack([x.ravel(), y.ravel()]) + rng.uniform(-0.5, 0.5, (x.size, 2)) * SPACING_MM
    xy = np.clip(xy, [-499.0, -299.0], [499.0, 299.0])
    if dent_mm:  # a point at the dent's centre in every scan
        xy = np.vstack([xy, [[150.0 + rng.uniform(-2, 2), 60.0 + rng.uniform(-2, 2)]]])
    z = _shape(xy[:, 0], xy[:, 1]) + rng.normal(0.0, 0.3, xy.shape[0])
    z -= dent_mm * np.exp(-((xy[:, 0] - 150.0) ** 2 + (xy[:, 1] - 60.0) ** 2) / (2 * sigma_mm**2))
    hit = rng.random(xy.shape[0]) < spikes
    z[hit] += rng.choice([-1.0, 1.0], hit.sum()) * rng.uniform(5.0, 50.0, hit.sum())
    return np.column_stack([xy, z])


def _union(*scans):
    return np.vstack(scans), np.concatenate([np.full(s.shape[0], i) for i, s in enumerate(scans)])


def test_one_scan_with_spikes_still_needs_review(design):
    result = compare(design, _scan(1), CompareOptions(tolerance_mm=TOLERANCE_MM, rotation_hint=np.eye(3)))
    assert result.verdict.kind == "needs_review" and result.set_aside.beyond_tolerance > 10
    assert result.set_aside.cleared == 0 and not result.is_cleared.any()
    # a single scan given as such: the same (issue 13's rule holds exactly)
    indexed = compare(design, _scan(1), CompareOptions(tolerance_mm=TOLERANCE_MM, rotation_hint=np.eye(3),
                      scan_index=np.zeros(result.n_points, int)))
    assert indexed.verdict.kind == "needs_review"
    assert indexed.set_aside.beyond_tolerance == result.set_aside.beyond_tolerance


def test_a_rescan_clears_the_first_scans_spikes(design):
    points, index = _union(_scan(1), _scan(2))
    result = compare(design, points, CompareOptions(tolerance_mm=TOLERANCE_MM, rotation_hint=np.eye(3),
            scan_index=index))
    aside = result.set_aside
    assert result.verdict.kind == "in_tolerance", result.headline
    assert aside.beyond_tolerance == 0 and aside.cleared > 20 and aside.confirmed == 0
    assert set(aside.cleared_by) == {0, 1} and sum(aside.cleared_by.values()) == aside.cleared
    assert result.is_cleared.sum() == aside.cleared
    assert "cleared by the first scan (" in result.headline and "rescan 1 (" in result.headline
    assert result.to_dict()["set_aside"]["cleared"] == aside.cleared
    assert result.verdict.to_dict()["set_aside_cleared"] == aside.cleared
    # without the scan of each point the same union is judged as one scan: needs review
    assert compare(design, points, CompareOptions(tolerance_mm=TOLERANCE_MM,
            rotation_hint=np.eye(3))).verdict.kind == "needs_review"


def test_a_narrow_dent_in_both_scans_is_never_passed(design):
    # one scan: the dent is one point, set aside like a spike (needs review, issue 13)
    dent = {"dent_mm": 8.0, "sigma_mm": 4.0}
    single = compare(design, _scan(1, **dent), CompareOptions(tolerance_mm=TOLERANCE_MM, rotation_hint=np.eye(3)))
    at_dent = np.hypot(single.measured_uv_mm[:, 0] - 150.0, single.measured_uv_mm[:, 1] - 60.0) < 10.0
    assert single.verdict.kind == "needs_review" and single.is_outlier[at_dent & (single.deviation_mm < -5.0)].all()
    # measured again at the same spot: confirmed, never cleared, never in tolerance
    points, index = _union(_scan(1, **dent), _scan(2, **dent))
    result = compare(design, points, CompareOptions(tolerance_mm=TOLERANCE_MM, rotation_hint=np.eye(3),
            scan_index=index))
    assert result.verdict.kind in ("needs_review", "out_of_tolerance"), result.headline
    at_dent = np.hypot(result.measured_uv_mm[:, 0] - 150.0, result.measured_uv_mm[:, 1] - 60.0) < 10.0
    deep = at_dent & (result.deviation_mm < -5.0)
    assert deep.sum() >= 2 and not result.is_cleared[deep].any()
    assert result.set_aside.confirmed >= 2 and result.set_aside.beyond_tolerance >= 2
    assert "measured so by two scans" in result.headline
    # the other spikes of the two scans are cleared all the same
    assert result.set_aside.cleared > 20


def test_two_spikes_at_one_spot_by_chance_are_not_a_confirmed_defect(design):
    # each scan has its spikes and, by chance, one more at nearly the same spot as the other's (10 mm apart, 40 and
    # 42 mm high: alike, as a real defect measured twice would be); each scan measured the plain surface right beside
    # the other's spike, a wall no plate has: both are artefacts, cleared like the rest
    first, second = _scan(1), _scan(2)
    first = np.vstack([first, [[-200.0, -100.0, _shape(-200.0, -100.0) + 40.0]]])
    second = np.vstack([second, [[-190.0, -100.0, _shape(-190.0, -100.0) + 42.0]]])
    points, index = _union(first, second)
    result = compare(design, points, CompareOptions(tolerance_mm=TOLERANCE_MM, rotation_hint=np.eye(3),
            scan_index=index))
    uv = result.measured_uv_mm
    pair = (np.hypot(uv[:, 0] + 195.0, uv[:, 1] + 100.0) < 8.0) & (result.deviation_mm > 30.0)
    assert pair.sum() == 2 and result.is_outlier[pair].all() and result.is_cleared[pair].all()
    assert result.set_aside.confirmed == 0 and result.verdict.kind == "in_tolerance", result.headline


def test_a_third_look_clears_a_chance_pair_but_never_a_dent(design):
    # two spikes alike at one spot, each scan's plain points too far to show a wall (the pair alone: confirmed) ...
    first = np.vstack([_scan(1, spikes=0.0), [[300.0, 200.0, _shape(300.0, 200.0) + 12.0]]])
    second = np.vstack([_scan(2, spikes=0.0), [[305.0, 200.0, _shape(305.0, 200.0) + 11.0]]])
    def far(scan):  # the spike, and no plain point within 12 mm of the spot
        return scan[(np.hypot(scan[:, 0] - 302.0, scan[:, 1] - 200.0) > 12.0)
                    | (np.abs(scan[:, 2] - _shape(scan[:, 0], scan[:, 1])) > 5.0)]

    first, second = far(first), far(second)
    options = {"tolerance_mm": TOLERANCE_MM, "rotation_hint": np.eye(3)}
    points, index = _union(first, second)
    pair = compare(design, points, CompareOptions(scan_index=index, **options))
    assert pair.set_aside.confirmed == 2 and pair.verdict.kind == "needs_review", pair.headline
    # ... a third scan that measured the plain surface 2 mm beside them (a 5 mm per mm wall) clears both
    third = np.vstack([_scan(3, spikes=0.0), [[301.0, 201.0, _shape(301.0, 201.0)]]])
    points, index = _union(first, second, third)
    looked = compare(design, points, CompareOptions(scan_index=index, **options))
    assert looked.set_aside.confirmed == 0 and looked.verdict.kind == "in_tolerance", looked.headline
    # two spikes 0.7 mm apart, 30 and 23 mm high (within 30 % of each other): a 10 mm per mm wall between
    # them, no one feature
    close_first = np.vstack([_scan(1, spikes=0.0), [[300.0, 200.0, _shape(300.0, 200.0) + 30.0]]])
    close_second = np.vstack([_scan(2, spikes=0.0), [[300.7, 200.0, _shape(300.7, 200.0) + 23.0]]])
    points, index = _union(far(close_first), far(close_second))
    steep = compare(design, points, CompareOptions(scan_index=index, **options))
    assert steep.set_aside.confirmed == 0 and steep.verdict.kind == "in_tolerance", steep.headline
    # a narrow dent measured by three scans stays confirmed: no scan can show a wall beside it
    dent = {"dent_mm": 8.0, "sigma_mm": 4.0, "spikes": 0.0}
    points, index = _union(_scan(1, **dent), _scan(2, **dent), _scan(3, **dent))
    dented = compare(design, points, CompareOptions(scan_index=index, **options))
    assert dented.set_aside.confirmed >= 2 and dented.verdict.kind != "in_tolerance", dented.headline


def test_confirmed_points_keep_the_verdict_from_in_tolerance():
    from mppf.measure.decision import REVIEW_ARTEFACTS, Figures, Limits, verdict

    limits = Limits(2.5, 1.0)
    confirmed = verdict(Figures(1.0, 0.4, set_aside=3, set_aside_beyond=1, set_aside_max_mm=7.0, confirmed_beyond=1),
                        limits)
    assert confirmed.kind == "needs_review" and confirmed.review_causes == (REVIEW_ARTEFACTS,)
    assert confirmed.only_rescannable and not confirmed.only_uncovered
    cleared = verdict(Figures(1.0, 0.4, set_aside=5, set_aside_cleared=5, cleared_by="cleared by rescan 1 (5)"), limits)
    assert cleared.in_tolerance and "5 beyond 2.5 mm cleared by rescan 1 (5)" in cleared.headline
    partly = verdict(Figures(1.0, 0.4, set_aside=5, set_aside_beyond=2, set_aside_max_mm=9.0, set_aside_cleared=3,
                             cleared_by="cleared by rescan 1 (3)"), limits)
    assert partly.kind == "needs_review" and "2 of 5 point(s)" in partly.headline
    assert "3 more cleared" in partly.headline
    assert not verdict(Figures(3.0, 0.4, set_aside_beyond=2), limits).only_rescannable
