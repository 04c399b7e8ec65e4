"""The step policy: the measured response, the share of the way, the best cycle to start from (correct/policy.py)."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.correct.policy import MIN_SHARE, Outcome, response_ratio, step_plan
from mppf.correct.step import outer_ring

ACTIVE = np.ones((6, 8), dtype=bool)
RING = outer_ring(ACTIVE)


def _field(seed: int, size_mm: float) -> np.ndarray:
    return size_mm * np.random.default_rng(seed).standard_normal(ACTIVE.shape)


def _cycles(errors, promises, maxima):
    return [Outcome(m, float(np.sqrt(np.mean(e**2))), e, p) for e, p, m in zip(errors, promises, maxima)]


def test_the_outer_ring_is_the_first_and_last_punch_of_every_row_and_column():
    active = np.zeros((5, 6), dtype=bool)
    active[1:4, 1:6] = True
    ring = outer_ring(active)
    assert ring[1, 1:6].all() and ring[3, 1:6].all() and ring[2, 1] and ring[2, 5] and not ring[2, 2:5].any()
    assert not ring[0].any() and not ring[:, 0].any() and ring.sum() == 5 + 5 + 2


def test_the_response_ratio_is_the_measured_over_the_promised_change_and_noise_pulls_it_to_one():
    promised = _field(1, 3.0)
    assert response_ratio(promised, 2.0 * promised, 0.0) == pytest.approx(2.0)
    assert response_ratio(promised, -promised, 0.0) == pytest.approx(-1.0)
    # promises within the noise teach nothing
    assert response_ratio(0.01 * promised, 0.03 * promised, 0.3) == pytest.approx(1.0, abs=0.05)


def test_a_correction_that_delivered_is_followed_at_full_share_from_the_last_strokes():
    e0 = _field(2, 8.0)
    promised = 0.1 * e0  # the correction promised to take 90 % off
    e1 = e0 + 2.0 * (promised - e0)  # the plate moved twice that: over-bent by 80 %, still better than before
    plan = step_plan(_cycles([e0, e1], [None, promised], [20.0, 19.0]), RING, 2.5, 1.0, noise_mm=0.1)
    assert plan.ratios[0] == pytest.approx(2.0, rel=0.02) and plan.edge_ratios[0] == pytest.approx(2.0, rel=0.05)
    assert plan.share == 1.0 and not plan.backtrack and plan.base == 1
    assert "moved 2.00 x what was promised" in plan.notes[0]


def test_a_correction_that_made_the_plate_worse_is_followed_by_a_half_step_from_the_best_cycle():
    e0, e1 = _field(3, 8.0), _field(4, 1.0)
    promised1, promised2 = 0.2 * e0, 0.1 * e1
    e2 = e1 + 0.5 * (promised2 - e1) + _field(5, 2.0)  # worse than cycle 2
    outcomes = _cycles([e0, e1, e2], [None, promised1, promised2], [20.0, 2.8, 6.0])
    plan = step_plan(outcomes, RING, 2.5, 1.0)
    assert plan.backtrack and plan.base == 1 and plan.share == 0.5
    assert "start from cycle 2's, 50% of the way" in plan.notes[-1]


def test_the_first_correction_is_full_size_and_a_plate_moved_against_the_promise_backtracks():
    assert step_plan(_cycles([_field(6, 5.0)], [None], [12.0]), RING, 2.5, 1.0).share == 1.0
    e0 = _field(7, 8.0)
    promised = 0.5 * e0
    e1 = e0 - 0.2 * (promised - e0)  # moved the other way (a little)
    plan = step_plan(_cycles([e0, e1], [None, promised], [20.0, 19.5]), RING, 2.5, 1.0)
    assert plan.ratios[0] < 0 and plan.backtrack and plan.share == 0.5
    # three bad corrections in a row: the share stops at MIN_SHARE
    outcomes = _cycles([e0, e1, e1 * 1.1, e1 * 1.2, e1 * 1.3], [None, promised, promised, promised, promised],
                       [20.0, 21.0, 22.0, 23.0, 24.0])
    assert step_plan(outcomes, RING, 2.5, 1.0).share == MIN_SHARE
