"""mppf's own thread count: ``MPPF_THREADS`` or up to two cores, and results that do not depend on it."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from mppf.core import threads
from mppf.core.threads import worker_threads


@pytest.mark.parametrize("value, expected", [("1", 1), ("3", 3), (" 2 ", 2), ("64", 64)])
def test_the_variable_sets_the_count(monkeypatch, value, expected):
    monkeypatch.setenv("MPPF_THREADS", value)
    assert worker_threads() == expected


def test_without_the_variable_up_to_two_cores(monkeypatch):
    monkeypatch.delenv("MPPF_THREADS", raising=False)
    assert worker_threads() == min(2, threads.cores())
    monkeypatch.setattr(threads, "cores", lambda: 1)
    assert worker_threads() == 1
    monkeypatch.setenv("MPPF_THREADS", "")
    assert worker_threads() == 1


@pytest.mark.parametrize("value", ["0", "-1", "two", "1.5", "65"])
def test_a_bad_value_is_ignored_with_one_warning(monkeypatch, caplog, value):
    monkeypatch.setenv("MPPF_THREADS", value)
    monkeypatch.setattr(threads, "_warned", set())
    with caplog.at_level(logging.WARNING, logger="mppf"):
        assert worker_threads() == min(2, threads.cores())
        assert worker_threads() == min(2, threads.cores())
    warnings = [r for r in caplog.records if "MPPF_THREADS" in r.getMessage()]
    assert len(warnings) == 1 and repr(value) in warnings[0].getMessage()


def test_local_fits_and_foot_points_are_the_same_on_one_thread_and_on_two(monkeypatch):
    """The chunks of local fits and the parts of the foot points run on threads: the same answers either way."""
    from scipy.spatial import cKDTree

    from mppf.geometry.surface import fit_plate
    from mppf.measure import deviations, localfit

    rng = np.random.default_rng(4)
    uv = rng.uniform(-1500.0, 1500.0, (3 * localfit.CHUNK, 2))  # three chunks
    values = 0.002 * uv[:, 0] - 1e-6 * uv[:, 1] ** 2 + rng.normal(0.0, 0.3, uv.shape[0])
    dist, idx = cKDTree(uv).query(uv, k=20)
    grid = np.linspace(-1500.0, 1500.0, 31)
    gu, gv = np.meshgrid(grid, grid)
    design = np.column_stack([gu.ravel(), gv.ravel(), 2e-5 * gu.ravel() ** 2 + 1e-5 * gv.ravel() ** 2])
    surface = fit_plate(design, kind="spline").surface
    near = np.column_stack([uv, 2e-5 * uv[:, 0] ** 2 + rng.normal(0.0, 2.0, uv.shape[0])])
    monkeypatch.setattr(deviations, "PARALLEL_POINTS", 1000)  # the foot points in parts too
    answers = []
    for count in ("1", "2"):
        monkeypatch.setenv("MPPF_THREADS", count)
        fitted = localfit.fits(uv, values, uv, (dist, idx), 20, terms=(3, 6))
        feet = deviations._foot_points(surface, near)
        answers.append((fitted[0].coef, fitted[1].variance, feet.uv, feet.distance_mm))
    for one, two in zip(*answers):
        np.testing.assert_array_equal(one, two)
