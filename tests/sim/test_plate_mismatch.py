"""The simulated steel plate off the nominal model by factors (sim/plate/mismatch.py)."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import InputError
from mppf.core.grid import without_plane
from mppf.model.press import example_press_path, load_press
from mppf.sim.plate.contact import Compliance
from mppf.sim.plate.material import PlateSteel
from mppf.sim.plate.mismatch import Mismatch, edge_field, mismatched_parts
from mppf.sim.plate.plate import SteelPlate
from mppf.sim.plate.scatter import NO_SCATTER

T_MM = 20.0
OUTLINE = np.array([[-600.0, -450.0], [600.0, -450.0], [600.0, 450.0], [-600.0, 450.0]])


@pytest.fixture(scope="module")
def press():
    return load_press(example_press_path())


def _bent(press, mismatch: Mismatch, k_per_mm: float = 2.5e-4):
    """Shape (n,) of a plate pressed on the tips of a bowl of curvature k, without its plane, mm."""
    steel, compliance, options = mismatched_parts(PlateSteel(), Compliance(), mismatch)
    plate = SteelPlate(press, OUTLINE, T_MM, steel, seed=None, scatter=NO_SCATTER, compliance=compliance,
                       grid_spacing_mm=75.0, **options)
    px, py = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    mid = 0.5 * T_MM + 0.5 * k_per_mm * (px**2 + py**2)
    formed = plate.press_step(mid + 0.5 * T_MM, mid - 0.5 * T_MM, np.ones(press.shape, dtype=bool))
    xy = formed.sample_xy(50.0)
    return xy, without_plane(xy[:, 0], xy[:, 1], formed.height_mm(xy[:, 0], xy[:, 1]))


def test_response_factor_scales_the_permanent_shape(press):
    _, nominal = _bent(press, Mismatch())
    _, double = _bent(press, Mismatch(response_factor=2.0))
    assert np.abs(nominal).max() > 1.0  # the bowl bent it plastically
    np.testing.assert_allclose(double, 2.0 * nominal, atol=1e-6 * np.abs(nominal).max())


def test_response_factor_after_the_first_step_scales_only_the_later_changes(press):
    steel, compliance, options = mismatched_parts(PlateSteel(), Compliance(), Mismatch(response_factor=3.0,
                                                                                       response_after_steps=1))
    plates = [SteelPlate(press, OUTLINE, T_MM, steel, seed=None, scatter=NO_SCATTER, compliance=compliance,
                         grid_spacing_mm=75.0, **opts) for opts in (options, {})]
    px, py = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    act = np.ones(press.shape, dtype=bool)
    shapes = []
    for plate in plates:
        for k in (2.0e-4, 3.0e-4):
            mid = 0.5 * T_MM + 0.5 * k * (px**2 + py**2)
            formed = plate.press_step(mid + 0.5 * T_MM, mid - 0.5 * T_MM, act)
            shapes.append(formed.height_mm(px, py))
    first, second, first_nominal, second_nominal = shapes
    np.testing.assert_allclose(first, first_nominal, atol=1e-9)  # the first step as modelled
    np.testing.assert_allclose(second - first, 3.0 * (second_nominal - first_nominal), atol=1e-6)
    # a saved and restored plate keeps its reference
    again = SteelPlate.from_state(plates[0].state_dict())
    np.testing.assert_allclose(again.formed.height_mm(px, py), second, atol=1e-9)


def test_a_higher_yield_stress_springs_back_more(press):
    _, nominal = _bent(press, Mismatch())
    _, harder = _bent(press, Mismatch(yield_factor=1.2))
    assert np.ptp(harder) < 0.9 * np.ptp(nominal)


def test_a_stiffer_edge_band_changes_the_edges_more_than_the_middle(press):
    xy, nominal = _bent(press, Mismatch())
    _, stiff = _bent(press, Mismatch(edge_factor=1.5))
    edge = np.min(np.array([600.0, 450.0]) - np.abs(xy), axis=1) < 100.0
    change = np.abs(stiff - nominal)
    assert change[edge].mean() > 1.5 * change[~edge].mean()


def test_parts_apply_each_factor():
    steel, compliance, options = mismatched_parts(PlateSteel(), Compliance(), Mismatch(
        yield_factor=1.1, hardening_factor=2.0, compliance_factor=3.0, anisotropy_factor=0.0, edge_factor=0.5))
    assert steel.yield_stress_mpa == pytest.approx(235.0 * 1.1)
    assert steel.swift_exponent == pytest.approx(0.2)
    assert steel.transverse_yield_ratio == 1.0
    assert compliance.frame_mm_per_mn == pytest.approx(1.5)
    assert options["edge_yield_factor"] == 0.5
    np.testing.assert_allclose(edge_field([[0.0, 0.0], [600.0, 0.0], [525.0, 0.0]], [1200.0, 900.0], 0.5, 150.0),
                               [1.0, 0.5, 0.75])
    assert Mismatch.named("edge", 2.0).label == "edge x2"


def test_a_factor_out_of_range_is_refused():
    with pytest.raises(InputError, match="yield_factor"):
        Mismatch(yield_factor=0.0)
