"""Plane polygons: outlines, containment, offsets, distances, moments."""

import numpy as np
import pytest

from mppf.core.errors import GeometryError, InputError
from mppf.core.polygon import (MITER_LIMIT, area, contains, convex_outline, convex_outline_index, distance_outside,
                               distance_to_outline, moments, offset_convex, perimeter)


def test_offset_of_a_square_is_a_bigger_square():
    square = np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])
    grown = offset_convex(square, 0.5)
    assert np.allclose(grown, [[-0.5, -0.5], [2.5, -0.5], [2.5, 2.5], [-0.5, 2.5]])
    # clockwise order: the same square, in its order
    assert np.allclose(offset_convex(square[::-1], 0.5), grown[::-1])
    assert np.allclose(offset_convex(square, 0.0), square)


def test_offset_moves_every_edge_by_the_margin():
    rng = np.random.default_rng(1)
    angles = np.sort(rng.uniform(0.0, 2 * np.pi, 9))
    poly = np.column_stack([300.0 * np.cos(angles) + 50.0, 200.0 * np.sin(angles) - 20.0])
    grown = offset_convex(poly, 25.0)
    for i in range(len(poly)):
        a, b = poly[i], poly[(i + 1) % len(poly)]
        ga, gb = grown[i], grown[(i + 1) % len(poly)]
        d = (b - a) / np.linalg.norm(b - a)
        e = (gb - ga) / np.linalg.norm(gb - ga)
        assert abs(d[0] * e[1] - d[1] * e[0]) < 1e-9  # parallel
        # 25 mm to the right of each edge of the counter-clockwise polygon: outward
        assert d[0] * (ga - a)[1] - d[1] * (ga - a)[0] == pytest.approx(-25.0)


def test_offset_guards_nearly_parallel_edges_and_sharp_corners():
    # a corner on a nearly straight edge moves by the margin, not far along the edge
    poly = np.array([[0.0, 0.0], [1000.0, 1e-7], [2000.0, 0.0], [2000.0, 1000.0], [0.0, 1000.0]])
    grown = offset_convex(poly, 10.0)
    assert np.allclose(grown[1], [1000.0, -10.0], atol=1e-6)
    assert np.allclose(grown[0], [-10.0, -10.0])
    # a repeated corner is dropped
    assert offset_convex(np.vstack([poly[:1], poly]), 10.0).shape == (5, 2)
    # a sharp corner: the miter is limited
    thin = np.array([[0.0, 0.0], [1000.0, -10.0], [1000.0, 10.0]])
    tip = offset_convex(thin, 5.0)[0]
    assert np.linalg.norm(tip) == pytest.approx(MITER_LIMIT * 5.0)
    assert tip[0] < 0 and abs(tip[1]) < 1e-9
    with pytest.raises(InputError):
        offset_convex(thin, -1.0)
    with pytest.raises(InputError):
        offset_convex(thin[:2], 1.0)


def test_distance_outside_a_polygon():
    square = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]) * 100
    pts = np.array([[0.0, 0.0], [99.0, 50.0], [130.0, 0.0], [130.0, 140.0], [-100.0, -100.0]])
    np.testing.assert_allclose(distance_outside(square, pts), [0.0, 0.0, 30.0, 50.0, 0.0], atol=1e-12)


def test_convex_outline_is_counter_clockwise_and_refuses_a_line():
    rng = np.random.default_rng(3)
    pts = rng.uniform(-1.0, 1.0, (200, 2)) * [300.0, 100.0]
    hull = convex_outline(pts)
    assert area(hull) > 0
    assert contains(hull, pts, tolerance_mm=1e-9).all()
    with pytest.raises(GeometryError, match="one line"):
        convex_outline(np.column_stack([np.arange(10.0), 2 * np.arange(10.0)]))
    with pytest.raises(GeometryError, match="at least 3"):
        convex_outline(pts[:2])


def test_contains_a_non_convex_polygon_either_direction():
    ell = np.array([[0.0, 0.0], [20.0, 0.0], [20.0, 10.0], [10.0, 10.0], [10.0, 20.0], [0.0, 20.0]])
    pts = np.array([[5.0, 5.0], [15.0, 15.0], [15.0, 5.0], [5.0, 15.0], [-1.0, 5.0], [25.0, 5.0]])
    expected = [True, False, True, True, False, False]
    assert contains(ell, pts).tolist() == expected
    assert contains(ell[::-1], pts).tolist() == expected
    # on the edge: only with a tolerance
    assert contains(ell, [[20.0 + 1e-3, 5.0]], tolerance_mm=0.01).tolist() == [True]
    assert contains(ell, [[20.0 + 1e-3, 5.0]]).tolist() == [False]


def test_distances_area_perimeter_and_moments_of_a_rectangle():
    rect = np.array([[0.0, 0.0], [400.0, 0.0], [400.0, 100.0], [0.0, 100.0]]) + 1.0e5  # hull-scale offset
    assert area(rect) == pytest.approx(40000.0)
    assert perimeter(rect) == pytest.approx(1000.0)
    np.testing.assert_allclose(distance_to_outline(rect, [[1.0e5 + 200.0, 1.0e5 + 30.0]]), [30.0])
    a, centre, second = moments(rect)
    assert a == pytest.approx(40000.0, rel=1e-9)
    np.testing.assert_allclose(centre, [1.0e5 + 200.0, 1.0e5 + 50.0], atol=1e-6)
    np.testing.assert_allclose(second, [[400.0**2 / 12, 0.0], [0.0, 100.0**2 / 12]], rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("kind", ["plate", "ring", "grid", "rounded", "circle"])
def test_convex_outline_has_the_corners_of_scipys_hull(kind):
    from scipy.spatial import ConvexHull

    rng = np.random.default_rng(len(kind))
    if kind == "plate":  # a plate's points, far from the origin
        pts = rng.uniform(-1.0, 1.0, (5000, 2)) * [1500.0, 750.0] + [2e5, -3e4]
    elif kind == "ring":
        angle = rng.uniform(0.0, 2 * np.pi, 3000)
        pts = np.column_stack([np.cos(angle), np.sin(angle)]) * rng.uniform(900.0, 1000.0, (3000, 1))
    elif kind == "grid":  # many points on each side, and a repeated corner
        pts = np.array([[x, y] for x in range(12) for y in range(7)], dtype=float) * 37.5 + [3.0, -2.0]
        pts = np.vstack([pts, pts[:1], pts[-1:]])
    elif kind == "rounded":  # whole numbers: points repeated and on the sides
        pts = np.round(rng.uniform(-5.0, 5.0, (400, 2)))
    else:  # every point a corner
        angle = rng.uniform(0.0, 2 * np.pi, 2000)
        pts = np.column_stack([np.cos(angle), np.sin(angle)]) * 1000.0
    index = convex_outline_index(pts)
    assert len(set(index.tolist())) == index.size
    assert sorted(map(tuple, pts[index])) == sorted(map(tuple, pts[ConvexHull(pts).vertices]))
    corners = pts[index]
    edges = np.roll(corners, -1, axis=0) - corners
    turns = edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - edges[:, 1] * np.roll(edges, -1, axis=0)[:, 0]
    assert np.all(turns > 0)  # counter-clockwise, every corner a real turn
    assert contains(corners, pts, tolerance_mm=1e-6).all()


def test_convex_outline_refuses_repeated_and_nearly_collinear_points():
    with pytest.raises(GeometryError, match="one line"):
        convex_outline(np.ones((5, 2)))
    t = np.linspace(0.0, 1.0, 50)
    with pytest.raises(GeometryError, match="one line"):  # 0.1 t, 0.7 t: on a line up to round-off
        convex_outline(np.column_stack([0.1 * t, 0.7 * t]))
    assert area(convex_outline(np.array([[0.0, 0.0], [1.0, 0.0], [0.5, 1e-6]]))) > 0  # thin but real
