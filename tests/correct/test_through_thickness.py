"""The correction's through-thickness model (mppf.correct.through_thickness): elastic below first yield, the
fully plastic moment of plane strain far above it, plastic memory, odd in the curvature."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.correct.through_thickness import BendingLaw, BendingState

T_MM = 20.0
LAW = BendingLaw(T_MM, youngs_modulus_mpa=206000.0, poisson=0.3, yield_stress_mpa=235.0)
SY_PLANE_STRAIN_MPA = 2.0 / np.sqrt(3.0) * LAW.yield_stress_mpa
"""Von Mises yield stress of a layer held flat across the bend (plane strain, plastic flow)."""


def _along_x(k_per_mm) -> np.ndarray:
    """Curvatures (n, 3) bending along x, held flat across (k_yy = 0), no twist."""
    k = np.atleast_1d(np.asarray(k_per_mm, dtype=float))
    return np.column_stack([k, np.zeros_like(k), np.zeros_like(k)])


def test_below_first_yield_the_plate_springs_back_flat_and_remembers_nothing():
    kappa = _along_x([0.2, 0.5, 0.95]) * LAW.elastic_limit_per_mm
    unloaded, state = LAW.press(kappa, BendingState.virgin(3))
    np.testing.assert_allclose(unloaded, 0.0, atol=1e-12 * LAW.elastic_limit_per_mm)
    assert not state.plastic_strain.any() and not state.alpha.any()


def test_far_above_first_yield_the_moment_is_the_fully_plastic_one_of_plane_strain():
    """M_xx -> sy' t^2 / 4 with sy' = 2 sy / sqrt 3, and M_yy -> M_xx / 2 (the layer's stress across is half)."""
    moment, _ = LAW.moment(_along_x(50.0 * LAW.elastic_limit_per_mm), BendingState.virgin(1))
    plastic_mm = SY_PLANE_STRAIN_MPA * T_MM**2 / 4.0
    assert moment[0, 0] == pytest.approx(plastic_mm, rel=0.01)
    assert moment[0, 1] == pytest.approx(0.5 * moment[0, 0], rel=0.02) and abs(moment[0, 2]) < 1e-9 * plastic_mm


def test_a_bend_past_yield_keeps_part_of_its_curvature_and_hardening_keeps_less():
    kappa = _along_x(3.0 * LAW.elastic_limit_per_mm)
    soft, _ = LAW.press(kappa, BendingState.virgin(1))
    hard, _ = BendingLaw(T_MM, hardening_mpa=2000.0).press(kappa, BendingState.virgin(1))
    assert 0.0 < soft[0, 0] < kappa[0, 0] and 0.0 < hard[0, 0] < soft[0, 0]
    assert soft[0, 1] < 0.0  # held flat across while loaded, it springs back anticlastic


def test_pressing_less_than_before_changes_nothing_and_a_reverse_bend_turns_it_over():
    kappa = _along_x(3.0 * LAW.elastic_limit_per_mm)
    first, state = LAW.press(kappa, BendingState.virgin(1))
    assert 0.6 * kappa[0, 0] > first[0, 0]
    for share in (1.0, 0.8, 0.6):  # the same bend again, or less but past what it kept: nothing changes
        again, later = LAW.press(share * kappa, state)
        np.testing.assert_allclose(again, first, rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(later.plastic_strain, state.plastic_strain, atol=1e-15)
    back, _ = LAW.press(-kappa, state)
    assert back[0, 0] < 0.0 < first[0, 0]  # a reverse bend past yield turns the residual curvature over


def test_the_law_is_odd_in_the_curvature():
    kappa = np.array([[3.0, -1.0, 0.8]]) * LAW.elastic_limit_per_mm
    up, _ = LAW.press(kappa, BendingState.virgin(1))
    down, _ = LAW.press(-kappa, BendingState.virgin(1))
    np.testing.assert_allclose(down, -up, rtol=1e-9)
