"""The polynomial plate surface: exact fits, conditioning, derivatives, degree choice (mppf.geometry.polynomial)."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import GeometryError, InputError
from mppf.geometry.polynomial import PolynomialSurface, fit_polynomial
from mppf.geometry.surface import Surface
from surface_helpers import OFFSET_MM, check_derivatives, known_bicubic, raw_poly, scattered_uv


def test_exact_recovery_of_a_known_bicubic():
    coef = known_bicubic()
    u, v = scattered_uv()
    surf = fit_polynomial(u, v, raw_poly(coef, u, v), degree=3)
    assert isinstance(surf, PolynomialSurface) and isinstance(surf, Surface)
    assert surf.degree == 3 and surf.kind == "poly" and surf.coefficients.shape == (4, 4)
    assert surf.rms_mm < 1e-9 and surf.max_abs_mm < 1e-8
    ut, vt = scattered_uv(200, seed=2)
    np.testing.assert_allclose(surf.evaluate(ut, vt), raw_poly(coef, ut, vt), atol=1e-8)


def test_conditioning_with_full_scale_hull_coordinates():
    # raw u^3 v^3 would be ~1e29 here: the fit must centre and scale
    coef = known_bicubic()
    u, v = scattered_uv()
    z = raw_poly(coef, u, v)
    surf = fit_polynomial(u + OFFSET_MM[0], v + OFFSET_MM[1], z, degree=3)
    assert surf.rms_mm < 1e-7
    np.testing.assert_allclose(surf.evaluate(u + OFFSET_MM[0], v + OFFSET_MM[1]), z, atol=1e-7)
    np.testing.assert_allclose(surf.center_mm, OFFSET_MM[:2], atol=5.0)


def test_derivatives_match_finite_differences_polynomial():
    coef = known_bicubic()
    u, v = scattered_uv()
    surf = fit_polynomial(u, v, raw_poly(coef, u, v), degree=3)
    check_derivatives(surf, *scattered_uv(50, seed=4))


def test_normals_are_unit_and_orthogonal_to_tangents():
    coef = known_bicubic()
    u, v = scattered_uv()
    surf = fit_polynomial(u, v, raw_poly(coef, u, v), degree=3)
    _, zu, zv, *_ = surf.derivatives(u, v)
    n = surf.normals(u, v)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    assert np.all(n[:, 2] > 0)
    np.testing.assert_allclose(n[:, 0] + n[:, 2] * zu, 0.0, atol=1e-12)  # . (1, 0, zu)
    np.testing.assert_allclose(n[:, 1] + n[:, 2] * zv, 0.0, atol=1e-12)  # . (0, 1, zv)


def test_evaluate_keeps_grid_shapes():
    u, v = scattered_uv()
    surf = fit_polynomial(u, v, u * v / 1e4, degree=2)
    gu, gv = np.meshgrid(np.linspace(-100, 100, 5), np.linspace(-50, 50, 4))
    assert surf.evaluate(gu, gv).shape == (4, 5)
    assert all(d.shape == (4, 5) for d in surf.derivatives(gu, gv))
    assert surf.normals(gu, gv).shape == (4, 5, 3)


@pytest.mark.parametrize("true_degree", [2, 3, 4])
def test_auto_degree_picks_the_generating_degree(true_degree):
    u, v = scattered_uv(1500)
    s, t = u / 1500.0, v / 1000.0
    z = 30 * s**2 + 20 * t**2 - 10 * s * t
    if true_degree >= 3:
        z = z + 25 * s**3 - 15 * s * t**2 + 12 * s**3 * t**3
    if true_degree == 4:
        z = z + 30 * s**4 * t**2 - 25 * t**4 + 20 * s**4 * t**4
    z = z + np.random.default_rng(5).normal(scale=0.05, size=z.shape)
    surf = fit_polynomial(u, v, z, degree="auto")
    assert surf.degree == true_degree
    assert [k for k, _ in surf.heldout_rms_mm] == [2, 3, 4]
    again = fit_polynomial(u, v, z, degree="auto")
    assert again.heldout_rms_mm == surf.heldout_rms_mm  # deterministic split


def test_polynomial_extends_smoothly_outside_bounds():
    coef = known_bicubic()
    u, v = scattered_uv()
    surf = fit_polynomial(u, v, raw_poly(coef, u, v), degree=3)
    far_u, far_v = np.array([1600.0, -1620.0]), np.array([1100.0, -1090.0])
    np.testing.assert_allclose(surf.evaluate(far_u, far_v), raw_poly(coef, far_u, far_v), atol=1e-7)


def test_fit_with_too_few_points_for_degree():
    u, v = scattered_uv(20)
    with pytest.raises(GeometryError, match="at least 25"):
        fit_polynomial(u, v, u * 0, degree=4)


def test_points_on_few_lines_do_not_determine_the_surface():
    u = np.repeat([-1000.0, 0.0, 1000.0], 20)  # three columns of points: rank deficient in u^3
    v = np.tile(np.linspace(-900, 900, 20), 3)
    with pytest.raises(GeometryError, match="rank"):
        fit_polynomial(u, v, u + v, degree=3)


def test_unknown_degree():
    u, v = scattered_uv(50)
    with pytest.raises(InputError, match="degree"):
        fit_polynomial(u, v, u, degree=5)


def test_mismatched_arrays():
    with pytest.raises(InputError, match="one length"):
        fit_polynomial(np.zeros(20), np.zeros(19), np.zeros(20))
