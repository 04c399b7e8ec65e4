"""The registration target built once: the same registrations as from an array, normals computed once
(mppf.registration.target)."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import GeometryError, InputError
from mppf.registration.register import register_icp
from mppf.registration.settings import RegisterOptions
from mppf.registration.target import build_target
from registration_helpers import PLATE_POSE, motion_error, sampled_scan


@pytest.mark.parametrize("method", ["point", "plane"])
def test_a_prebuilt_target_gives_the_registration_of_the_array(method):
    design, scan = sampled_scan(4000, 1500, seed=3)
    target = build_target(design)
    for _ in range(2):  # built once, used twice: the second run sees the normals of the first
        from_target = register_icp(scan, target, RegisterOptions(method=method))
        from_array = register_icp(scan, design, RegisterOptions(method=method))
        np.testing.assert_array_equal(from_target.tf, from_array.tf)
        assert from_target.rms_history == from_array.rms_history
        assert from_target.uncertainty == from_array.uncertainty
    assert motion_error(from_target.tf, PLATE_POSE, scan.mean(axis=0))[0] < 1.0  # registered (point-to-point: a coarse turn)


def test_normals_are_computed_once_and_are_unit_pca_normals():
    design, _ = sampled_scan(5000, 10, seed=4)
    target = build_target(design)
    idx = np.arange(0, 5000, 7)
    first = target.normals(idx)
    np.testing.assert_allclose(np.linalg.norm(first, axis=1), 1.0, atol=1e-12)
    assert np.all(np.abs(first @ target.frame.axes[2]) > 0.9)  # a shallow plate: near its plane's normal
    cached = target._normals.copy()
    np.testing.assert_array_equal(target.normals(idx[::-1])[::-1], first)
    np.testing.assert_array_equal(target._normals, cached)  # nothing computed again


def test_a_normal_another_thread_is_still_writing_is_computed_again_not_returned_half_written():
    """The start fits share the target on two threads; numpy may release the GIL while a thread writes its rows,
    so another can see a row whose first component is written and the rest still NaN (not computed)."""
    design, _ = sampled_scan(3000, 10, seed=5)
    target = build_target(design)
    whole = target.normals(np.arange(3000)).copy()
    target._normals[7] = [whole[7, 0], np.nan, np.nan]  # row 7 half written
    np.testing.assert_allclose(target.normals(np.array([7, 8])), whole[[7, 8]], atol=1e-12)


def test_target_checks_its_points():
    with pytest.raises(InputError, match="NaN or infinite"):
        build_target([[0.0, 0.0, 0.0], [1.0, 0.0, np.nan], [0.0, 1.0, 0.0]], "the design skin")
    with pytest.raises(GeometryError, match="collinear"):
        build_target(np.outer(np.arange(10.0), [1.0, 2.0, 3.0]))
    # a point-to-plane registration needs enough target points for the normals
    target = build_target(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.1]]))
    with pytest.raises(GeometryError, match="at least 10"):
        register_icp(np.random.default_rng(0).normal(size=(20, 3)), target, RegisterOptions(method="plane"))


def test_a_target_of_the_same_points_is_built_once_and_kept_for_the_latest_few(monkeypatch):
    from mppf.registration import target as target_module

    monkeypatch.setattr(target_module, "_kept", type(target_module._kept)())
    design, scan = sampled_scan(3000, 1500, seed=6)
    first = build_target(design, "the design skin")
    assert build_target(design.copy(), "the design skin") is first  # by content, not by the array
    assert build_target(design, "another name") is not first
    moved = design + [0.0, 0.0, 1e-9 * 1024]
    assert build_target(moved, "the design skin") is not first  # one coordinate bit differs: another target
    for k in range(target_module.KEPT_TARGETS):
        build_target(design + [0.0, 0.0, k + 1.0], "the design skin")
    rebuilt = build_target(design, "the design skin")
    assert rebuilt is not first  # the oldest was let go
    # a kept target (normals of earlier registrations filled in) registers as a new one
    register_icp(scan[::2], rebuilt, RegisterOptions(method="plane"))  # fills in the normals of the points it met
    assert np.isfinite(rebuilt._normals).all(axis=1).any()
    warm = register_icp(scan, build_target(design, "the design skin"), RegisterOptions(method="plane"))
    monkeypatch.setattr(target_module, "_kept", type(target_module._kept)())
    cold = register_icp(scan, build_target(design, "the design skin"), RegisterOptions(method="plane"))
    np.testing.assert_array_equal(warm.tf, cold.tf)
    assert warm.rms_history == cold.rms_history


def test_a_kept_target_is_its_own_copy_of_the_points(monkeypatch):
    """A caller that changes its array after a registration does not change the target kept for that content."""
    from mppf.registration import target as target_module

    monkeypatch.setattr(target_module, "_kept", type(target_module._kept)())
    design, _ = sampled_scan(2000, 10, seed=8)
    original = design.copy()
    kept = build_target(design)
    design[:, 2] += 50.0  # the caller's array, changed in place
    np.testing.assert_array_equal(kept.points, original)
    assert build_target(original) is kept and build_target(design) is not kept
    with pytest.raises(ValueError):
        kept.points[0, 0] = 1.0  # read-only
