"""Closed-form and press checks of the FE plate, with the real CalculiX (slow: each runs ccx).

1. The section: a wide plate (plane strain) and a strip bent to a cylinder and released keep the
   residual curvature of the elastic-perfectly-plastic moment-curvature law
   ``kappa_r = kappa - M(kappa) / (E' I)`` within 2 % (docs/simulator-fe.md derives it).
2. Flat strokes (lower tips 0, upper tips at the thickness) leave the plate flat.
3. Strokes to a cylinder beyond the elastic radius ``R_e = E' t / (2 sy')`` spring back flat.
4. The plate's state (the press steps it had) saved and restored presses on like the original.
"""

from __future__ import annotations

import numpy as np
import pytest
from mppf.sim.fe.checks import moment_curvature_residual, residual_curvature
from mppf.sim.fe.plate import FEPlate
from mppf.sim.plate.material import PlateSteel
from mppf.sim.plate.scatter import NO_SCATTER

from mppf.model.press import example_press_path, load_press

pytestmark = pytest.mark.slow

T_MM = 20.0
OUTLINE = np.array([[-600.0, -400.0], [600.0, -400.0], [600.0, 400.0], [-600.0, 400.0]])
EPP = PlateSteel(swift_exponent=0.0, linear_hardening_mpa=0.0)


@pytest.fixture(scope="module")
def press():
    return load_press(example_press_path())


def cylinder_tips(press, radius_mm: float):
    """Tips (upper, lower, active) holding the mid-surface on z = t/2 - x^2 / (2 R)."""
    x, _ = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    mid = 0.5 * T_MM - x ** 2 / (2.0 * radius_mm)
    return mid + 0.5 * T_MM, mid - 0.5 * T_MM, np.ones(press.shape, dtype=bool)


@pytest.mark.parametrize("wide", [True, False])
@pytest.mark.parametrize("ratio", [3.0, 6.0])
def test_bent_section_keeps_the_residual_curvature_of_the_moment_curvature_law(wide, ratio):
    e = EPP.youngs_modulus_mpa / (1 - EPP.poisson ** 2) if wide else EPP.youngs_modulus_mpa
    sy = EPP.yield_stress_mpa * (2 / np.sqrt(3) if wide else 1.0)
    kappa = ratio * 2 * sy / (e * T_MM)
    expected = moment_curvature_residual(EPP, T_MM, kappa, wide=wide)
    got = residual_curvature(EPP, T_MM, kappa, layers=4, wide=wide)
    assert got == pytest.approx(expected, rel=0.02)
    assert 0.2 * kappa < got < kappa  # it did yield and it did spring back


def test_flat_strokes_leave_the_plate_flat(press):
    plate = FEPlate(press, OUTLINE, T_MM, PlateSteel(), seed=None, scatter=NO_SCATTER, cells_per_pitch=1)
    upper, lower, active = np.full(press.shape, T_MM), np.zeros(press.shape), np.ones(press.shape, dtype=bool)
    formed = plate.press_step(upper, lower, active)
    mid = formed.mid_surface_points(50.0)
    assert np.abs(mid[:, 2] - 0.5 * T_MM).max() < 0.05
    top = formed.top_skin_points(50.0)
    assert np.abs(top[:, 2] - T_MM).max() < 0.05


def test_elastic_strokes_spring_back_flat_and_the_state_presses_on(press):
    plate = FEPlate(press, OUTLINE, T_MM, PlateSteel(), seed=None, scatter=NO_SCATTER, cells_per_pitch=1)
    radius = 3.0 * plate.plate.steel.youngs_modulus_mpa / (1 - 0.09) * T_MM / (2 * 1.155 * 235.0)
    formed = plate.press_step(*cylinder_tips(press, radius))
    x = np.linspace(-450.0, 450.0, 19)
    loaded = formed.height_mm(x, 0 * x, loaded=True)
    free = formed.height_mm(x, 0 * x)
    sag = loaded.max() - loaded.min()
    assert sag == pytest.approx(450.0 ** 2 / (2 * radius), rel=0.1)  # it was bent
    assert free.max() - free.min() < 0.02 * sag  # and sprang back flat
    # the saved state (the press steps to replay) presses the next step like the plate itself
    again = FEPlate.from_state(plate.state_dict())
    assert np.allclose(again.formed.height_mm(x, 0 * x), free)
    flat = np.full(press.shape, T_MM), np.zeros(press.shape), np.ones(press.shape, dtype=bool)
    one, two = plate.press_step(*flat), again.press_step(*flat)
    assert np.allclose(one.height_mm(x, 0 * x), two.height_mm(x, 0 * x), atol=1e-6)
    assert np.abs(one.height_mm(x, 0 * x) - 0.5 * T_MM).max() < 0.1
