"""Grid helpers: planes, curvature tensors, integration, thin-plate fill, neighbour differences."""

import numpy as np
import pytest

from mppf.core.grid import (best_plane, from_principal, hessian, integrate_hessian, largest_neighbour_difference,
                            neighbour_differences, neighbour_mean, plane_values, principal, tps_fill, without_plane)


def test_best_plane_recovers_a_plane_and_the_robust_fit_ignores_a_spike():
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-1000.0, 1000.0, (2, 400))
    z = 3.0 + 0.01 * x - 0.02 * y
    np.testing.assert_allclose(best_plane(x, y, z), [3.0, 0.01, -0.02], atol=1e-9)
    spiked = z.copy()
    spiked[:10] += 50.0
    assert not np.allclose(best_plane(x, y, spiked), [3.0, 0.01, -0.02], atol=1e-3)
    np.testing.assert_allclose(best_plane(x, y, spiked, robust=True), [3.0, 0.01, -0.02], atol=1e-9)
    # NaN values are left out; without_plane keeps them NaN
    z_nan = z.copy()
    z_nan[5] = np.nan
    rest = without_plane(x, y, z_nan)
    assert np.isnan(rest[5]) and np.nanmax(np.abs(rest)) < 1e-9
    np.testing.assert_allclose(plane_values([1.0, 2.0, 3.0], [1.0], [1.0]), [6.0])


def test_hessian_principal_directions_and_back_on_a_twisted_bowl():
    x = np.linspace(-500.0, 500.0, 51)
    y = np.linspace(-300.0, 300.0, 31)
    gx, gy = np.meshgrid(x, y)
    kxx, kxy, kyy = 1 / 5000.0, 1 / 20000.0, -1 / 8000.0
    z = 0.5 * kxx * gx**2 + kxy * gx * gy + 0.5 * kyy * gy**2
    hxx, hxy, hyy = hessian(z, x[1] - x[0], y[1] - y[0])
    np.testing.assert_allclose([hxx[15, 25], hxy[15, 25], hyy[15, 25]], [kxx, kxy, kyy], rtol=1e-9)
    kappa, vec = principal(hxx, hxy, hyy)
    assert kappa.shape == z.shape + (2,) and vec.shape == z.shape + (2, 2)
    np.testing.assert_allclose(from_principal(kappa, vec)[15, 25], [[kxx, kxy], [kxy, kyy]], rtol=1e-9, atol=1e-15)
    # the curvature field integrates back to the heights, up to a plane
    back = integrate_hessian(hxx, hxy, hyy, x[1] - x[0], y[1] - y[0])
    np.testing.assert_allclose(without_plane(gx, gy, back), without_plane(gx, gy, z), atol=0.05)


def test_tps_fill_interpolates_and_reproduces_a_plane():
    rng = np.random.default_rng(2)
    known = rng.uniform(0.0, 1000.0, (30, 2))
    values = 2.0 + 0.003 * known[:, 0] - 0.001 * known[:, 1]
    query = rng.uniform(100.0, 900.0, (20, 2))
    np.testing.assert_allclose(tps_fill(known, values, query), 2.0 + 0.003 * query[:, 0] - 0.001 * query[:, 1],
                               atol=1e-6)
    np.testing.assert_allclose(tps_fill(known, values, known), values, atol=1e-9)


def test_neighbour_differences_and_means():
    values = np.array([[0.0, 1.0, 3.0], [2.0, 2.0, 2.0]])
    active = np.array([[True, True, True], [True, False, True]])
    (dx, ax, bx), (dy, ay, by) = neighbour_differences(values, active)
    assert sorted(dx.tolist()) == [1.0, 2.0] and sorted(dy.tolist()) == [-1.0, 2.0]
    assert largest_neighbour_difference(values, active) == pytest.approx(2.0)
    assert largest_neighbour_difference(values, np.zeros_like(active)) == 0.0
    mean = neighbour_mean(values, active)
    assert mean[0, 0] == pytest.approx((1.0 + 2.0) / 2) and mean[1, 1] == pytest.approx((1.0 + 2.0 + 2.0) / 3)
