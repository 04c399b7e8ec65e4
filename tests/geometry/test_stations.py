"""Hull stations (mppf.geometry.stations): traced from the keel, girths exact, their ends found.

Checked on a box-bilge hull written by gmsh, whose station is known exactly at every girth
(flat bottom, a circular bilge, a vertical side: :func:`cad_helpers.box_hull_point`).
"""

from __future__ import annotations

import numpy as np
import pytest

from cad_helpers import BOX_BILGE_MM, BOX_DEPTH_MM, BOX_HALF_BREADTH_MM, box_hull_point, write_box_hull
from mppf.core.errors import GeometryError
from mppf.geometry.cad import CadModel
from mppf.geometry.stations import sample_girth, trace_stations

DECK_GIRTH_MM = BOX_HALF_BREADTH_MM - BOX_BILGE_MM + 0.5 * np.pi * BOX_BILGE_MM + BOX_DEPTH_MM - BOX_BILGE_MM
"""Girth of the box hull's deck edge from the keel (20712.4 mm)."""


@pytest.fixture(scope="module")
def box(tmp_path_factory):
    with CadModel(write_box_hull(tmp_path_factory.mktemp("box") / "box.step")) as model:
        yield model


def test_a_traced_station_lies_on_the_hull_and_ends_at_the_deck(box):
    stations = np.array([1000.0, 15000.0])
    points, girth, normal = trace_stations(box, stations, 2 * DECK_GIRTH_MM)
    assert points.shape[:2] == girth.shape == normal.shape[:2] and points.shape[0] == 2
    assert np.all(np.diff(girth, axis=1) >= 0.0)  # non-decreasing along each station
    np.testing.assert_allclose(girth[:, -1], DECK_GIRTH_MM, atol=10.0)  # the station ends at the deck edge
    np.testing.assert_allclose(points[:, :, 0], np.repeat(stations[:, None], girth.shape[1], axis=1), atol=1e-6)
    for k in range(2):  # each point where the exact station is at its girth
        np.testing.assert_allclose(points[k, :, 1:], box_hull_point(girth[k]), atol=0.5)
    np.testing.assert_allclose(np.linalg.norm(normal, axis=2), 1.0, atol=1e-9)
    np.testing.assert_allclose(normal[:, :, 0], 0.0, atol=1e-9)  # in the plane x = const


def test_a_station_stops_at_the_girth_asked_for(box):
    points, girth, _ = trace_stations(box, [5000.0], 8000.0, step_mm=250.0)
    assert 8000.0 <= girth[0, -1] < 8000.0 + 250.0 and np.ptp(points[0, :, 0]) == 0.0
    steps = np.diff(girth[0])
    assert np.max(steps) <= 1.01 * 250.0  # a step's chord is at most 250 mm; its arc a little more on the bilge
    np.testing.assert_allclose(steps[girth[0, 1:] < 6900.0], 250.0, atol=1e-6)  # on the flat bottom: exact


def test_girth_is_exact_on_a_box_bilge_hull(box):
    girth = np.array([0.0, 150.0, 6999.0, 7000.0, 8200.0, 11700.0, 11713.0, 15000.0, 20000.0])
    stations = np.array([500.0, 10000.0, 19500.0])
    points = sample_girth(box, stations, girth)
    np.testing.assert_allclose(points[:, :, 0], np.repeat(stations[:, None], girth.size, axis=1), atol=1e-6)
    np.testing.assert_allclose(points[:, :, 1:], np.broadcast_to(box_hull_point(girth), (3, girth.size, 2)),
                               atol=0.05)


def test_a_station_that_ends_before_the_plate(box):
    with pytest.raises(GeometryError, match="ends at a girth of 2071[0-9] mm"):
        sample_girth(box, [1000.0], [20000.0, 21000.0])
    with pytest.raises(GeometryError, match="no keel at x = 25000 mm"):
        sample_girth(box, [25000.0], [100.0])
