"""The formed steel plate as the scanner sees it, seeding, and saving and restoring a plate."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import InputError
from mppf.core.transform import apply_tf, invert_tf
from mppf.model.press import example_press_path, load_press
from mppf.sim.plate.grid import plate_frame
from mppf.sim.plate.plate import SteelPlate
from mppf.sim.plate.scatter import Scatter
from mppf.sim.scanner import SimulatedScanner

T_MM = 20.0
OUTLINE = np.array([[-750.0, -525.0], [750.0, -525.0], [750.0, 525.0], [-750.0, 525.0]])


@pytest.fixture(scope="module")
def press():
    return load_press(example_press_path())


def _tips(press, kx, ky):
    """(upper, lower) holding the mid-surface on t/2 + kx x^2/2 + ky y^2/2 (ball geometry)."""
    px, py = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    mid = 0.5 * T_MM + 0.5 * kx * px**2 + 0.5 * ky * py**2
    s = np.sqrt(1.0 + (kx * px) ** 2 + (ky * py) ** 2)
    r = press.tip_radius_mm
    return mid - r + (r + 0.5 * T_MM) * s, mid + r - (r + 0.5 * T_MM) * s


@pytest.fixture(scope="module")
def pressed(press):
    """A scattered plate (thickness field of 5 % RMS, to see it) after one saddle step."""
    plate = SteelPlate(press, OUTLINE, T_MM, seed=11, scatter=Scatter(thickness_field=0.05))
    upper, lower = _tips(press, 1 / 3000.0, -1 / 6000.0)
    plate.press_step(upper, lower, np.ones(press.shape, dtype=bool))
    return plate


def test_the_top_skin_is_the_mid_surface_plus_half_the_local_thickness(pressed):
    formed = pressed.formed
    xy = formed.sample_xy(40.0)
    local = formed.thickness_at(xy)
    assert np.ptp(local) > 1.0  # the thickness does vary over this plate
    normals = formed.normals(xy)
    assert np.allclose(np.linalg.norm(normals, axis=1), 1.0) and np.all(normals[:, 2] > 0.9)
    mid = np.column_stack([xy, formed.height_mm(xy[:, 0], xy[:, 1])])
    top = formed.offset_points(xy, 0.5 * formed.thickness_mm)
    bottom = formed.skin_points(40.0, side=-1.0)
    assert np.allclose(top - mid, 0.5 * local[:, None] * normals)
    assert np.allclose(formed.top_skin_points(40.0), top)
    assert np.allclose(bottom, mid - 0.5 * local[:, None] * normals)
    # the normals are those of the mid-surface: compare with finite differences
    h = 1e-3
    zx = (formed.height_mm(xy[:, 0] + h, xy[:, 1]) - formed.height_mm(xy[:, 0] - h, xy[:, 1])) / (2 * h)
    zy = (formed.height_mm(xy[:, 0], xy[:, 1] + h) - formed.height_mm(xy[:, 0], xy[:, 1] - h)) / (2 * h)
    expected = np.column_stack([-zx, -zy, np.ones_like(zx)])
    assert np.allclose(normals, expected / np.linalg.norm(expected, axis=1, keepdims=True), atol=1e-6)


def test_the_formed_plate_grid_and_samples_follow_the_scanner_contract(pressed):
    formed = pressed.formed
    assert formed.unloaded_z_mm.shape == (len(formed.y_mm), len(formed.x_mm)) == formed.loaded_z_mm.shape
    xx, yy = np.meshgrid(formed.x_mm, formed.y_mm)
    assert np.allclose(formed.height_mm(xx, yy), formed.unloaded_z_mm)
    assert np.allclose(formed.height_mm(xx, yy, loaded=True), formed.loaded_z_mm)
    xy = formed.sample_xy(100.0)
    # centred on the outline's box: the rows and columns left over are the same on both sides
    assert np.allclose(xy.min(axis=0) + xy.max(axis=0), 0.0) and len(xy) == 16 * 11
    assert formed.mid_surface_points(100.0).shape == (len(xy), 3)
    assert formed.contact_xyz_mm.shape[1] == 3 and len(formed.contact_xyz_mm) > 20
    assert np.nansum(formed.lower_force_n) > 0 and np.nansum(formed.upper_force_n) > 0
    assert 0.0 < formed.mean_ratio < 1.0
    with pytest.raises(InputError, match="spacing"):
        formed.sample_xy(0.0)


def test_the_simulated_scanner_scans_the_real_top_skin(pressed):
    formed = pressed.formed
    scan = SimulatedScanner(noise_mm=0.0, occlusion_fraction=0.2, outlier_fraction=0.0, seed=3).sample(formed)
    points = apply_tf(invert_tf(scan.tf_scan_press), scan.points)
    # the foot of each point on the mid-surface (fixed point of p_xy - t_local/2 n_xy)
    xy = points[:, :2].copy()
    for _ in range(6):
        xy = points[:, :2] - 0.5 * formed.thickness_at(xy)[:, None] * formed.normals(xy)[:, :2]
    # noise-free scan points lie on the top skin: half the local thickness above the mid-surface
    assert np.abs(formed.offset_points(xy, 0.5 * formed.thickness_mm) - points).max() < 1e-6
    assert 0.1 < scan.occluded_fraction < 0.3


def test_the_same_seed_gives_the_same_plate_and_another_seed_another(press):
    upper, lower = _tips(press, 1 / 4000.0, 0.0)
    active = np.ones(press.shape, dtype=bool)
    shapes = [SteelPlate(press, OUTLINE, T_MM, seed=s).press_step(upper, lower, active).unloaded_z_mm
              for s in (4, 4, 5)]
    assert np.array_equal(shapes[0], shapes[1])
    assert np.abs(shapes[0] - shapes[2]).max() > 0.1


def test_a_saved_plate_resumes_exactly(pressed, press, tmp_path):
    path = tmp_path / "plate.npz"
    np.savez(path, **pressed.state_dict())
    with np.load(path) as saved:
        restored = SteelPlate.from_state(saved)
    assert restored.steps == pressed.steps == 1
    assert np.array_equal(restored.formed.unloaded_z_mm, pressed.formed.unloaded_z_mm)
    # the next step from both gives the same plate (the saved one is not changed by it)
    upper, lower = _tips(press, 1 / 2500.0, -1 / 5000.0)
    active = np.ones(press.shape, dtype=bool)
    state = pressed.state_dict()
    twin = SteelPlate.from_state(state)
    a = twin.press_step(upper, lower, active)
    b = restored.press_step(upper, lower, active)
    assert np.array_equal(a.unloaded_z_mm, b.unloaded_z_mm)
    assert np.array_equal(state["q"], pressed.q)
    broken = dict(state, alpha=state["alpha"][:-1])
    with pytest.raises(InputError, match="alpha"):
        SteelPlate.from_state(broken)
    with pytest.raises(InputError, match="lacks"):
        SteelPlate.from_state({"q": state["q"]})


def test_a_plate_placed_at_an_angle_gets_its_own_frame(press):
    angle = np.radians(20.0)
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    corners = np.array([[-600.0, -350.0], [600.0, -350.0], [600.0, 350.0], [-600.0, 350.0]]) @ rot.T + [100.0, 50.0]
    centre, frame_angle, size = plate_frame(corners)
    assert np.allclose(centre, [100.0, 50.0]) and np.allclose(size, [1200.0, 700.0])
    assert frame_angle == pytest.approx(angle)
    plate = SteelPlate(press, corners, T_MM, seed=1)
    assert plate.grid.gauss_weight_mm2.sum() == pytest.approx(1200.0 * 700.0)
    upper, lower = _tips(press, 1 / 5000.0, 0.0)
    formed = plate.press_step(upper, lower, np.ones(press.shape, dtype=bool))
    inside = formed.sample_xy(50.0)
    assert np.all(np.isfinite(formed.height_mm(inside[:, 0], inside[:, 1])))
    assert np.isnan(formed.unloaded_z_mm).any()  # the corners of the press-aligned box are off the plate
