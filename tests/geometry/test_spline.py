"""The B-spline plate surface: pieces, derivatives, extension beyond its bounds, smoothing (mppf.geometry.spline)."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.core.errors import InputError
from mppf.geometry.polynomial import fit_polynomial
from mppf.geometry.spline import SplineSurface, fit_spline
from mppf.geometry.surface import Surface
from surface_helpers import check_derivatives, knuckle_plate, scattered_uv


def test_spline_beats_polynomial_where_one_polynomial_does_not_hold():
    u, v, z = knuckle_plate()
    poly = fit_polynomial(u, v, z, degree=4)
    spline = fit_spline(u, v, z)
    assert isinstance(spline, SplineSurface) and isinstance(spline, Surface)
    assert spline.kind == "spline" and spline.degree == 3
    assert poly.rms_mm > 1.0
    assert spline.rms_mm < poly.rms_mm / 5
    assert spline.max_abs_mm < poly.max_abs_mm / 5


def test_spline_pieces_equal_the_scipy_spline_inside():
    u, v, z = knuckle_plate()
    spline = fit_spline(u, v, z)
    uq, vq = scattered_uv(300, length_mm=2990, width_mm=1990, seed=12)
    ours = spline.derivatives(uq, vq)
    for value, (du, dv) in zip(ours, [(0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2)]):
        ref = spline.spline.ev(uq, vq, dx=du, dy=dv)
        np.testing.assert_allclose(value, ref, rtol=1e-9, atol=1e-10 * np.abs(ref).max())


def test_spline_derivatives_inside_and_outside_bounds():
    u, v, z = knuckle_plate()
    spline = fit_spline(u, v, z)
    (umin, umax), (vmin, vmax) = spline.bounds
    inside_u, inside_v = scattered_uv(40, length_mm=2800, width_mm=1800, seed=9)
    check_derivatives(spline, inside_u, inside_v, h=1e-3)
    # beyond one edge (u) and beyond a corner, by up to 100 mm (away from the kinks at the edge lines)
    check_derivatives(spline, np.full(10, umax + 60.0), np.linspace(vmin + 50, vmax - 50, 10), h=1e-3)
    check_derivatives(spline, np.linspace(umin + 50, umax - 50, 10), np.full(10, vmin - 80.0), h=1e-3)
    check_derivatives(spline, np.full(3, umin - 70.0), np.full(3, vmax + 90.0), h=1e-3)


def test_spline_extension_is_continuous_and_first_order():
    u, v, z = knuckle_plate()
    spline = fit_spline(u, v, z)
    (_, umax), _ = spline.bounds
    vs = np.linspace(-900, 900, 7)
    edge_z, edge_zu = spline.derivatives(np.full(7, umax), vs)[:2]
    eps = 1e-6
    np.testing.assert_allclose(spline.evaluate(np.full(7, umax + eps), vs), edge_z, atol=1e-5)
    np.testing.assert_allclose(spline.derivatives(np.full(7, umax + eps), vs)[1], edge_zu, atol=1e-7)
    np.testing.assert_allclose(spline.evaluate(np.full(7, umax + 100.0), vs), edge_z + 100.0 * edge_zu, atol=1e-9)


def test_heights_are_those_of_the_derivatives_to_the_last_bit_inside_and_beyond_the_bounds():
    u, v, z = knuckle_plate()
    spline = fit_spline(u, v, z)
    (umin, umax), (vmin, vmax) = spline.bounds
    rng = np.random.default_rng(4)
    uq = rng.uniform(umin - 300.0, umax + 300.0, 2000)  # about a third beyond the bounds
    vq = rng.uniform(vmin - 300.0, vmax + 300.0, 2000)
    assert np.array_equal(spline.evaluate(uq, vq), spline.derivatives(uq, vq)[0])
    inside = spline.evaluate(np.clip(uq, umin, umax), np.clip(vq, vmin, vmax))
    assert np.array_equal(inside, spline.derivatives(np.clip(uq, umin, umax), np.clip(vq, vmin, vmax))[0])
    assert spline.evaluate(uq[:6].reshape(2, 3), vq[:6].reshape(2, 3)).shape == (2, 3)


def test_spline_bridges_a_hole_in_the_scan():
    # no data in the middle: the knot grid coarsens instead of inventing a shape there
    u, v = scattered_uv(3000, seed=13)
    z = u**2 / 8000.0 + 30.0 * np.sin(u / 300.0) + np.random.default_rng(2).normal(scale=0.5, size=u.shape)
    keep = (np.abs(u) > 700) | (np.abs(v) > 500)
    spline = fit_spline(u[keep], v[keep], z[keep])
    g = np.linspace(-600.0, 600.0, 7)
    np.testing.assert_allclose(spline.evaluate(g, np.zeros(7)), g**2 / 8000.0 + 30.0 * np.sin(g / 300.0), atol=2.0)


def test_spline_smoothing_targets_the_rms():
    u, v, z = knuckle_plate()
    noisy = z + np.random.default_rng(3).normal(scale=0.5, size=z.shape)
    spline = fit_spline(u, v, noisy, smoothing=0.8)
    assert spline.smoothing == 0.8
    assert spline.rms_mm == pytest.approx(0.8, rel=0.05)


def test_spline_smoothing_must_be_positive():
    u, v, z = knuckle_plate(100)
    with pytest.raises(InputError, match="smoothing"):
        fit_spline(u, v, z, smoothing=-1.0)


@pytest.mark.parametrize("even", [True, False])
def test_knot_cell_of_every_point_is_the_binary_search_one(even):
    """The cell index from the knot spacing equals searchsorted's, on the knots, beside them and beyond."""
    from mppf.geometry.spline import _cell, _even_step

    rng = np.random.default_rng(7)
    for _ in range(50):
        n = int(rng.integers(2, 14))
        lo, hi = rng.uniform(-5000.0, 0.0), rng.uniform(100.0, 9000.0)
        breaks = np.linspace(lo, hi, n) if even else np.unique(rng.uniform(lo, hi, n))
        if len(breaks) < 2:
            continue
        c = np.concatenate([rng.uniform(lo - 100.0, hi + 100.0, 2000), breaks,
                            np.nextafter(breaks, -np.inf), np.nextafter(breaks, np.inf)])
        expected = np.clip(np.searchsorted(breaks, c, side="right") - 1, 0, len(breaks) - 2)
        assert (_even_step(breaks) is not None) == even or len(breaks) == 2
        assert np.array_equal(_cell(breaks, c, _even_step(breaks)), expected)
        assert np.array_equal(_cell(breaks, c), expected)
