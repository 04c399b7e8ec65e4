"""Helpers of the surface tests (tests/geometry): scattered points, known polynomials, derivative checks."""

from __future__ import annotations

import numpy as np

RNG = np.random.default_rng(11)
OFFSET_MM = np.array([176000.0, 12500.0, 4200.0])


def scattered_uv(n=600, length_mm=3000.0, width_mm=2000.0, seed=1):
    rng = np.random.default_rng(seed)
    return rng.uniform([-length_mm / 2, -width_mm / 2], [length_mm / 2, width_mm / 2], size=(n, 2)).T


def raw_poly(coef, u, v):
    """sum c_ij u^i v^j on raw (unscaled) mm coordinates, as a test oracle."""
    return sum(coef[i, j] * u**i * v**j for i in range(coef.shape[0]) for j in range(coef.shape[1]))


def known_bicubic():
    # terms sized to give a few 10 mm over a 3 x 2 m plate
    scale = np.array([[1.0, 1e-3, 1e-6, 1e-9]]).T * np.array([[1.0, 1e-3, 1e-6, 1e-9]])
    return RNG.uniform(-20.0, 20.0, size=(4, 4)) * scale


def check_derivatives(surf, u, v, h=1e-2):
    z, zu, zv, zuu, zuv, zvv = surf.derivatives(u, v)
    np.testing.assert_allclose(z, surf.evaluate(u, v), atol=1e-12)
    d = lambda du, dv: surf.derivatives(u + du, v + dv)  # noqa: E731
    tol = dict(rtol=1e-5, atol=1e-8)
    np.testing.assert_allclose(zu, (d(h, 0)[0] - d(-h, 0)[0]) / (2 * h), **tol)
    np.testing.assert_allclose(zv, (d(0, h)[0] - d(0, -h)[0]) / (2 * h), **tol)
    np.testing.assert_allclose(zuu, (d(h, 0)[1] - d(-h, 0)[1]) / (2 * h), **tol)
    np.testing.assert_allclose(zuv, (d(0, h)[1] - d(0, -h)[1]) / (2 * h), **tol)
    np.testing.assert_allclose(zvv, (d(0, h)[2] - d(0, -h)[2]) / (2 * h), **tol)


def knuckle_plate(n=2500):
    u, v = scattered_uv(n, seed=8)
    return u, v, 40.0 * np.tanh(u / 300.0) + v**2 / 20000.0
