"""The simulated steel plate on the example press: contact, compliance, plastic memory, grid."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import GeometryError, InputError
from mppf.core.grid import without_plane
from mppf.model.press import example_press_path, load_press
from mppf.sim.plate.contact import RIGID, Compliance
from mppf.sim.plate.plate import SteelPlate
from mppf.sim.plate.scatter import NO_SCATTER

T_MM = 20.0
OUTLINE = np.array([[-750.0, -525.0], [750.0, -525.0], [750.0, 525.0], [-750.0, 525.0]])


@pytest.fixture(scope="module")
def press():
    return load_press(example_press_path())


def _tips(press, kx, ky, thickness_mm=T_MM):
    """(upper, lower, mid) holding the mid-surface on t/2 + kx x^2/2 + ky y^2/2 (ball geometry)."""
    px, py = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    mid = 0.5 * thickness_mm + 0.5 * kx * px**2 + 0.5 * ky * py**2
    s = np.sqrt(1.0 + (kx * px) ** 2 + (ky * py) ** 2)
    r = press.tip_radius_mm
    return mid - r + (r + 0.5 * thickness_mm) * s, mid + r - (r + 0.5 * thickness_mm) * s, mid


def _all(press):
    return np.ones(press.shape, dtype=bool)


def _shape(formed, spacing_mm=50.0):
    """The unloaded mid-surface on a grid inside the outline, without its best-fit plane, mm."""
    xy = formed.sample_xy(spacing_mm)
    return without_plane(xy[:, 0], xy[:, 1], formed.height_mm(xy[:, 0], xy[:, 1]))


def _edge_pairs(plate):
    """Pairs of the outermost ring over the plate (within a pitch of the outline's bounding box)."""
    xy = plate.punches.xy_mm
    lo, hi = OUTLINE.min(axis=0) + 150.0, OUTLINE.max(axis=0) - 150.0
    return np.any((xy < lo) | (xy > hi), axis=1)


def test_flat_strokes_give_a_flat_plate(press):
    # a real (scattered) plate, compliant press: flat strokes bend it only elastically
    plate = SteelPlate(press, OUTLINE, T_MM, seed=5)
    upper, lower, _ = _tips(press, 0.0, 0.0)
    formed = plate.press_step(upper, lower, _all(press))
    assert plate.state.alpha.max() == 0.0
    assert np.abs(_shape(formed)).max() < 1e-6
    assert np.nansum(formed.lower_force_n) > 0


def test_without_springback_and_compliance_the_plate_keeps_the_pressed_shape(press):
    # gentle shape: every active pair holds the mid-surface midway between its tips
    plate = SteelPlate(press, OUTLINE, T_MM, seed=None, scatter=NO_SCATTER, compliance=RIGID, springback=False)
    upper, lower, _ = _tips(press, 1 / 8000.0, -1 / 20000.0)
    formed = plate.press_step(upper, lower, _all(press))
    xy = plate.punches.xy_mm
    midway = plate.punches.pick(0.5 * (upper + lower))
    assert np.abs(formed.height_mm(xy[:, 0], xy[:, 1]) - midway).max() < 0.05
    assert np.allclose(formed.unloaded_z_mm, formed.loaded_z_mm, equal_nan=True)
    # strong shape: inside the outer ring; at the outer ring the free edge makes the plate
    # flatter than designed and the balls hold it with play (they touch it off their axes)
    plate = SteelPlate(press, OUTLINE, T_MM, seed=None, scatter=NO_SCATTER, compliance=RIGID, springback=False)
    upper, lower, _ = _tips(press, 1 / 3000.0, -1 / 7500.0)
    formed = plate.press_step(upper, lower, _all(press))
    error = np.abs(formed.height_mm(xy[:, 0], xy[:, 1]) - plate.punches.pick(0.5 * (upper + lower)))
    inner = ~_edge_pairs(plate)
    assert inner.sum() >= 40 and error[inner].max() < 0.05
    assert error[~inner].max() < 2.0


def test_contact_is_unilateral_and_parked_pairs_do_not_touch(press):
    plate = SteelPlate(press, OUTLINE, T_MM, seed=None, scatter=NO_SCATTER)
    upper, lower, _ = _tips(press, 0.0, 0.0)
    # the upper tips 30 mm up: the plate lies on the lower tips under its weight only
    formed = plate.press_step(upper + 30.0, lower, _all(press))
    weight_n = plate.plate.steel.density_kg_mm3 * 9810.0 * 1e-3 * T_MM * 1500.0 * 1050.0
    assert np.nansum(formed.upper_force_n) == 0.0
    assert np.nansum(formed.lower_force_n) == pytest.approx(weight_n, rel=1e-3)
    # parked pairs (NaN tips) carry nothing, and what they would say does not matter
    active = _all(press)
    active[:, ::2] = False
    upper, lower, _ = _tips(press, 1 / 4000.0, 0.0)
    results = []
    for junk in (np.nan, 0.0):
        bent = SteelPlate(press, OUTLINE, T_MM, seed=None, scatter=NO_SCATTER)
        formed = bent.press_step(np.where(active, upper, junk), np.where(active, lower, junk), active)
        assert np.all(np.nan_to_num(formed.lower_force_n[~active]) == 0.0)
        assert np.all(np.nan_to_num(formed.upper_force_n[~active]) == 0.0)
        results.append(formed.unloaded_z_mm)
    assert np.array_equal(results[0], results[1], equal_nan=True)


def test_press_compliance_bends_the_plate_less(press):
    upper, lower, _ = _tips(press, 1 / 3000.0, 1 / 6000.0)
    plates = {}
    for name, compliance in (("rigid", RIGID), ("compliant", Compliance())):
        plates[name] = SteelPlate(press, OUTLINE, T_MM, seed=None, scatter=NO_SCATTER, compliance=compliance)
        plates[name].press_step(upper, lower, _all(press))
    rigid, compliant = plates["rigid"], plates["compliant"]
    assert rigid.frame_mm.max() == 0.0 and 0.05 < compliant.frame_mm.min() < compliant.frame_mm.max() < 1.0

    def bend(plate):
        return -plate.grid.curvatures(plate.q)[:, :2].mean()

    assert bend(compliant) < 0.99 * bend(rigid)
    # the loaded mid-surfaces differ at the punches by about the frame's deflection
    diff = compliant.punches.mid_surface_mm(compliant.loaded_q) - rigid.punches.mid_surface_mm(rigid.loaded_q)
    assert 0.5 * compliant.frame_mm.min() < np.abs(diff).max() < 2.0 * compliant.frame_mm.sum()


def test_plastic_memory_pressing_less_changes_nothing_and_unbending_needs_reverse_bending(press):
    plate = SteelPlate(press, OUTLINE, T_MM, seed=None, scatter=NO_SCATTER, compliance=Compliance(frame_mm_per_mn=0.0))
    radius = 2500.0
    upper, lower, _ = _tips(press, 1 / radius, 0.0)
    first = _shape(plate.press_step(upper, lower, _all(press)))
    middle = np.abs(plate.grid.gauss_uv[:, 0]) < 400.0
    kappa_f = -plate.grid.curvatures(plate.q)[middle, 0].mean()
    assert 1.0 / kappa_f > 1.5 * radius  # the unloaded plate is flatter than the re-press
    # re-pressed to 1.5 R (less than it was loaded to): it springs back to the same shape
    upper, lower, _ = _tips(press, 1 / (1.5 * radius), 0.0)
    again = _shape(plate.press_step(upper, lower, _all(press)))
    assert np.abs(again - first).max() < 0.05
    # pressed flat: reverse bending past the reversed yield, the plate un-bends
    upper, lower, _ = _tips(press, 0.0, 0.0)
    plate.press_step(upper, lower, _all(press))
    assert -plate.grid.curvatures(plate.q)[middle, 0].mean() < 0.8 * kappa_f


def test_halving_the_grid_spacing_changes_the_formed_plate_little(press):
    upper, lower, _ = _tips(press, 1 / 2500.0, -1 / 6000.0)
    shapes = []
    for spacing in (50.0, 25.0):
        plate = SteelPlate(press, OUTLINE, T_MM, seed=2, grid_spacing_mm=spacing)
        shapes.append(_shape(plate.press_step(upper, lower, _all(press)), 25.0))
    assert np.ptp(shapes[1]) > 50.0
    assert np.abs(shapes[0] - shapes[1]).max() < 0.2
    assert np.sqrt(np.mean((shapes[0] - shapes[1]) ** 2)) < 0.05


def test_press_step_rejects_bad_strokes(press):
    plate = SteelPlate(press, OUTLINE, T_MM, seed=None, scatter=NO_SCATTER)
    upper, lower, _ = _tips(press, 0.0, 0.0)
    active = _all(press)
    with pytest.raises(InputError, match="shape"):
        plate.press_step(upper[:, :-1], lower, active)
    with pytest.raises(InputError, match="NaN"):
        plate.press_step(np.where(active, np.nan, upper), lower, active)
    with pytest.raises(InputError, match="crush"):
        plate.press_step(lower + 0.2 * T_MM, lower, active)
    with pytest.raises(GeometryError, match="at least 3"):
        plate.press_step(upper, lower, np.zeros(press.shape, dtype=bool))
    assert plate.steps == 0
