"""The elastic-plastic springback model shared by the planner and the simulated forming."""

import numpy as np
import pytest

from mppf.core.errors import InputError
from mppf.model.material import Material
from mppf.forming.springback import loaded_curvature, springback_ratio, unloaded_curvature

STEEL = Material(youngs_modulus_mpa=206000.0, poisson=0.3, yield_stress_mpa=235.0)
T_MM = 20.0
# c = sy' / (E' t): the curvature scale of the model, in 1/mm
C = STEEL.plane_strain_yield_mpa / (STEEL.plane_strain_modulus_mpa * T_MM)


def test_plane_strain_constants():
    assert STEEL.plane_strain_modulus_mpa == pytest.approx(206000.0 / 0.91)
    assert STEEL.plane_strain_yield_mpa == pytest.approx(1.155 * 235.0)


def test_ratio_is_one_for_a_sharp_bend_and_zero_at_the_elastic_limit():
    radius_at_x = lambda x: x / C  # noqa: E731  (x = R c)
    assert springback_ratio(radius_at_x(1e-6), T_MM, STEEL) == pytest.approx(1.0, abs=1e-5)
    assert springback_ratio(radius_at_x(0.5), T_MM, STEEL) == pytest.approx(0.0, abs=1e-12)
    # beyond the elastic limit the plate springs back flat, whatever the radius
    for x in (0.6, 0.8, 1.0, 5.0):
        assert springback_ratio(radius_at_x(x), T_MM, STEEL) == 0.0
    assert springback_ratio(np.inf, T_MM, STEEL) == 0.0


def test_ratio_decreases_monotonically_up_to_the_elastic_limit():
    x = np.linspace(1e-4, 0.5, 400)
    ratio = springback_ratio(x / C, T_MM, STEEL)
    assert np.all(np.diff(ratio) < 0)
    np.testing.assert_allclose(ratio, 4 * x**3 - 3 * x + 1, atol=1e-12)


def test_final_curvature_in_closed_form():
    kappa_i = np.array([2.5, 3.0, 5.0, 20.0]) * C
    expected = kappa_i - 3 * C + 4 * C**3 / kappa_i**2
    np.testing.assert_allclose(unloaded_curvature(kappa_i, T_MM, STEEL), expected, rtol=1e-12)
    np.testing.assert_allclose(unloaded_curvature(-kappa_i, T_MM, STEEL), -expected, rtol=1e-12)
    assert unloaded_curvature(0.0, T_MM, STEEL) == 0.0


@pytest.mark.parametrize("radius_mm", [3300.0, 4700.0, 12300.0, 30000.0, -26400.0, 257000.0])
def test_loaded_curvature_inverts_the_springback(radius_mm):
    kappa_f = np.array([1.0 / radius_mm])
    kappa_i = loaded_curvature(kappa_f, T_MM, STEEL)
    assert abs(kappa_i[0]) > abs(kappa_f[0])  # always an over-bend
    assert np.sign(kappa_i[0]) == np.sign(kappa_f[0])
    assert abs(kappa_i[0]) >= 2 * C  # it must yield to keep any curvature
    np.testing.assert_allclose(unloaded_curvature(kappa_i, T_MM, STEEL), kappa_f, rtol=1e-9)


def test_bad_material_is_refused():
    with pytest.raises(InputError, match="Poisson"):
        Material(poisson=0.7)
    with pytest.raises(InputError, match="yield"):
        Material(yield_stress_mpa=-1.0)
