"""Closed-form checks of the simulated steel plate: pure bending of a wide plate to a cylinder.

A wide plate (plane strain: ``cylindrical=True``, w = w(u)) is pressed by a row of punch
pairs at 50 mm pitch that hold it exactly on a cylinder of radius R (the tips follow the
ball geometry), then springs back free. In its middle part the loaded curvature is
uniform and the residual curvature must follow the moment-curvature law:

    kappa_f = kappa_i - M(kappa_i) / D',      D' = E' t^3 / 12,  E' = E / (1 - nu^2)

with M of the elastic-perfectly-plastic section, ``M = sy' t^2 / 4 (1 - (kappa_e / kappa_i)^2 / 3)``,
``kappa_e = 2 sy' / (E' t)``, plus, with linear hardening, the bilinear term (docs/simulator-plate.md).
"""

from __future__ import annotations

import numpy as np
import pytest

from mppf.model.press import example_press_path, load_press, press_from_dict
from mppf.sim.plate.contact import Compliance
from mppf.sim.plate.material import PlateSteel
from mppf.sim.plate.plate import SteelPlate
from mppf.sim.plate.scatter import NO_SCATTER

T_MM = 20.0
PITCH_MM = 50.0
COLS = 21
HALF_MM = 0.5 * PITCH_MM * (COLS - 1) + 25.0
STRIP = np.array([[-HALF_MM, -30.0], [HALF_MM, -30.0], [HALF_MM, 30.0], [-HALF_MM, 30.0]])
NO_FRAME = Compliance(frame_mm_per_mn=0.0, punch_mm_per_kn=0.002)  # stiff punches: uniform bending


@pytest.fixture(scope="module")
def row_press():
    """One row of punch pairs at 50 mm pitch with 10 mm balls (the outer rows lie off the strip)."""
    doc = load_press(example_press_path()).to_dict()
    doc["matrix"].update(rows=3, cols=COLS, pitch_x_mm=PITCH_MM, pitch_y_mm=100.0, tip_radius_mm=10.0)
    return press_from_dict(doc)


def _cylinder_tips(press, radius_mm):
    """(upper, lower) holding the mid-surface on z = t/2 + x^2 / (2 R), ball geometry."""
    px, _ = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    mid = 0.5 * T_MM + px**2 / (2.0 * radius_mm)
    s = np.sqrt(1.0 + (px / radius_mm) ** 2)
    r = press.tip_radius_mm
    return mid - r + (r + 0.5 * T_MM) * s, mid + r - (r + 0.5 * T_MM) * s


def _bend(press, steel, radius_mm):
    """(loaded, unloaded) mean curvature d2w/du2 of the middle 60 % of the strip, 1/mm, and the plate."""
    plate = SteelPlate(press, STRIP, T_MM, steel, seed=None, scatter=NO_SCATTER, compliance=NO_FRAME,
                       grid_spacing_mm=25.0, cylindrical=True)
    upper, lower = _cylinder_tips(press, radius_mm)
    plate.press_step(upper, lower, np.ones(press.shape, dtype=bool))
    middle = np.abs(plate.grid.gauss_uv[:, 0]) < 0.3 * 2 * HALF_MM
    loaded = -plate.grid.curvatures(plate.loaded_q)[middle, 0]
    unloaded = -plate.grid.curvatures(plate.q)[middle, 0]
    assert np.std(loaded) < 0.01 * np.mean(loaded)  # the middle is uniformly bent
    return np.mean(loaded), np.mean(unloaded), plate


def _residual_curvature(kappa_i, yield_ps_mpa, modulus_ps_mpa, plastic_modulus_ps_mpa=0.0):
    """Closed-form kappa_f of plane-strain pure bending (bilinear section)."""
    stiffness = modulus_ps_mpa * T_MM**3 / 12.0
    k_e = 2.0 * yield_ps_mpa / (modulus_ps_mpa * T_MM)
    x = k_e / kappa_i
    moment = yield_ps_mpa * T_MM**2 / 4.0 * (1.0 - x**2 / 3.0)
    if plastic_modulus_ps_mpa:
        tangent = modulus_ps_mpa * plastic_modulus_ps_mpa / (modulus_ps_mpa + plastic_modulus_ps_mpa)
        core = 0.5 * T_MM * x
        moment += tangent * 2.0 * (kappa_i * ((T_MM / 2) ** 3 - core**3) / 3.0
                                   - yield_ps_mpa / modulus_ps_mpa * ((T_MM / 2) ** 2 - core**2) / 2.0)
    return kappa_i - moment / stiffness


@pytest.mark.parametrize("poisson", [0.3, 0.4999])
@pytest.mark.parametrize("radius_mm", [1500.0, 2500.0, 3500.0])
def test_pure_bending_springs_back_by_the_moment_curvature_law(row_press, poisson, radius_mm):
    steel = PlateSteel(poisson=poisson, swift_exponent=0.0, transverse_yield_ratio=1.0)
    kappa_i, kappa_f, _ = _bend(row_press, steel, radius_mm)
    assert kappa_i == pytest.approx(1.0 / radius_mm, rel=0.01)
    expected = _residual_curvature(kappa_i, 2.0 / np.sqrt(3.0) * steel.yield_stress_mpa,
                                   steel.plane_strain_modulus_mpa)
    assert kappa_f == pytest.approx(expected, rel=0.02)


@pytest.mark.parametrize("radius_mm", [1500.0, 2500.0, 3500.0])
def test_pure_bending_with_linear_hardening_follows_its_closed_form(row_press, radius_mm):
    hardening = 20000.0
    steel = PlateSteel(poisson=0.4999, swift_exponent=0.0, linear_hardening_mpa=hardening, transverse_yield_ratio=1.0)
    kappa_i, kappa_f, _ = _bend(row_press, steel, radius_mm)
    expected = _residual_curvature(kappa_i, 2.0 / np.sqrt(3.0) * steel.yield_stress_mpa,
                                   steel.plane_strain_modulus_mpa, 4.0 / 3.0 * hardening)
    assert kappa_f == pytest.approx(expected, rel=0.02)
    # and it differs from the elastic-perfectly-plastic answer by much more than that
    plain = _residual_curvature(kappa_i, 2.0 / np.sqrt(3.0) * steel.yield_stress_mpa, steel.plane_strain_modulus_mpa)
    assert abs(plain - expected) > 0.05 * expected


def test_bending_below_first_yield_springs_back_flat(row_press):
    steel = PlateSteel(swift_exponent=0.0, transverse_yield_ratio=1.0)
    elastic_radius = steel.plane_strain_modulus_mpa * T_MM / (2.0 * 2.0 / np.sqrt(3.0) * steel.yield_stress_mpa)
    kappa_i, kappa_f, plate = _bend(row_press, steel, 1.3 * elastic_radius)
    assert kappa_i == pytest.approx(1.0 / (1.3 * elastic_radius), rel=0.01)
    assert abs(kappa_f) < 1e-6 * kappa_i
    assert plate.state.alpha.max() == 0.0
    formed = plate.formed
    xy = formed.sample_xy(20.0)
    z = formed.height_mm(xy[:, 0], xy[:, 1])
    assert np.ptp(z) < 1e-4


def test_bending_along_and_across_the_rolling_direction_springs_back_by_the_yield_ratio(row_press):
    ratio = 1.06
    springback = {}
    for angle in (0.0, 90.0):
        steel = PlateSteel(transverse_yield_ratio=ratio, rolling_angle_deg=angle, swift_exponent=0.0)
        kappa_i, kappa_f, _ = _bend(row_press, steel, 2500.0)
        springback[angle] = kappa_i - kappa_f
    # bending strains the fibres along u: the rolling direction at 0 deg, across it at 90 deg
    assert springback[90.0] / springback[0.0] - 1.0 == pytest.approx(ratio - 1.0, rel=0.15)
