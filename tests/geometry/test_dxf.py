"""The flat plate for the NC cutter (mppf.geometry.dxf): outlines read back with ezdxf against the flat."""

from __future__ import annotations

import ezdxf
import numpy as np
import pytest

from mppf.core.polygon import area, contains, convex_outline, distance_to_outline, offset_convex, perimeter
from mppf.core.transform import apply_tf
from mppf.geometry.dxf import LAYERS, flat_drawing, write_flat_dxf
from mppf.geometry.mesh import boundary_edges
from mppf.geometry.read import read_points
from mppf.geometry.unfold import unfold
from mppf.model.job_parts import reference_corner_xy
from mppf.planning.placement import place_flat
from mppf.model.press import example_press_path, load_press


@pytest.fixture(scope="module", params=["K1_midbody_bilge", "K3_stern_saddle"])
def unfolded(request, hull_dir):
    return unfold(read_points(hull_dir / f"{request.param}.csv").points)


def _read_back(path):
    doc = ezdxf.readfile(path)
    polylines = {name: [np.array(e.get_points("xy"), dtype=float) for e in
                        doc.modelspace().query(f'LWPOLYLINE[layer=="{name}"]')] for name in ("CUT", "NET")}
    return doc, polylines


def _flat_area_and_outline(result) -> tuple[float, float]:
    """The flat's area (its triangles) and outline length (its boundary edges), straight from the unfolding."""
    xy, tri = result.flat[:, :2], result.faces
    a, b, c = xy[tri[:, 0]], xy[tri[:, 1]], xy[tri[:, 2]]
    triangles = 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    edges = boundary_edges(tri)
    return float(triangles.sum()), float(np.linalg.norm(xy[edges[:, 0]] - xy[edges[:, 1]], axis=1).sum())


def test_outlines_read_back_match_the_flat(unfolded, tmp_path):
    margin = 100.0
    path = write_flat_dxf(tmp_path / "flat.dxf", flat_drawing(unfolded.flat, unfolded.faces, margin, label="K"))
    doc, polylines = _read_back(path)
    assert not doc.audit().has_errors
    assert doc.header["$INSUNITS"] == 4 and doc.header["$MEASUREMENT"] == 1  # millimetres
    assert set(LAYERS) <= {layer.dxf.name for layer in doc.layers}
    assert all(e.closed for e in doc.modelspace().query("LWPOLYLINE"))
    (cut,), (net,) = polylines["CUT"], polylines["NET"]
    # the net outline: the unfolded plate's area and outline length
    flat_area, flat_outline = _flat_area_and_outline(unfolded)
    assert abs(area(net)) == pytest.approx(flat_area, rel=1e-9)
    assert perimeter(net) == pytest.approx(flat_outline, rel=1e-9)
    # the cut outline: the flat's convex outline grown by the margin (as the planner lays the plate)
    grown = offset_convex(convex_outline(unfolded.flat[:, :2]), margin)
    assert area(cut) == pytest.approx(area(grown), rel=1e-9)
    assert perimeter(cut) == pytest.approx(perimeter(grown), rel=1e-9)
    assert area(cut) > flat_area + margin * flat_outline  # at least the band all round
    assert np.all(contains(cut, net)) and distance_to_outline(cut, net).min() >= margin - 1e-6


def test_reference_mark_is_the_cut_corner_with_the_smallest_x_plus_y(unfolded, tmp_path):
    path = write_flat_dxf(tmp_path / "flat.dxf", flat_drawing(unfolded.flat, unfolded.faces, 100.0))
    doc, polylines = _read_back(path)
    cut = polylines["CUT"][0]
    (point,) = doc.modelspace().query('POINT[layer=="MARK"]')
    (circle,) = doc.modelspace().query('CIRCLE[layer=="MARK"]')
    mark = np.array(point.dxf.location)[:2]
    np.testing.assert_allclose(mark, reference_corner_xy(cut), atol=1e-9)
    assert contains(cut, np.array(circle.dxf.center)[None, :2])[0]  # the circle is on the plate
    assert any(t.dxf.text == "REF" for t in doc.modelspace().query('TEXT[layer=="TEXT"]'))


def test_the_mark_is_the_corner_the_planner_lays_at_the_first_punch(unfolded):
    """On the press, as the planner lays a flat from mppf unfold, the mark is the corner nearest row 1, column 1."""
    press = load_press(example_press_path())
    drawing = flat_drawing(unfolded.flat, unfolded.faces, press.margin_mm)
    placed = place_flat(unfolded.flat, press, 20.0)
    cut_on_press = apply_tf(placed.tf_press_flat, np.column_stack([drawing.cut_mm, np.zeros(len(drawing.cut_mm))]))
    mark_on_press = apply_tf(placed.tf_press_flat, np.r_[drawing.mark_mm, 0.0][None])[0, :2]
    np.testing.assert_allclose(mark_on_press, reference_corner_xy(cut_on_press[:, :2]), atol=1e-6)
    first_punch = np.array([press.punch_x_mm[0], press.punch_y_mm[0]])
    corners = cut_on_press[:, :2]
    nearest = corners[np.argmin(np.linalg.norm(corners - first_punch, axis=1))]
    assert np.linalg.norm(nearest - mark_on_press) < 1e-6


def test_no_margin_cuts_the_net_outline(unfolded, tmp_path):
    path = write_flat_dxf(tmp_path / "net.dxf", flat_drawing(unfolded.flat, unfolded.faces, 0.0))
    _, polylines = _read_back(path)
    np.testing.assert_allclose(polylines["CUT"][0], polylines["NET"][0])


def test_punch_centres_in_the_flat_coordinates(unfolded, tmp_path):
    turn = np.array([[0.0, -1.0, 0.0, 50.0], [1.0, 0.0, 0.0, -20.0], [0.0, 0.0, 1.0, 10.0], [0, 0, 0, 1.0]])
    punches_press = np.array([[0.0, 0.0], [300.0, 200.0], [-600.0, 100.0]])
    drawing = flat_drawing(unfolded.flat, unfolded.faces, 50.0, tf_press_flat=turn, punches_press_mm=punches_press)
    path = write_flat_dxf(tmp_path / "punch.dxf", drawing)
    doc, _ = _read_back(path)
    centres = np.array([c.dxf.center for c in doc.modelspace().query('CIRCLE[layer=="PUNCH"]')])[:, :2]
    back = apply_tf(turn, np.column_stack([centres, np.zeros(len(centres))]))[:, :2]
    np.testing.assert_allclose(back, punches_press, atol=1e-9)
    # the mark: smallest x + y on the press, here a quarter turn away from the flat's own
    on_press = apply_tf(turn, np.column_stack([drawing.cut_mm, np.zeros(len(drawing.cut_mm))]))[:, :2]
    np.testing.assert_allclose(apply_tf(turn, np.r_[drawing.mark_mm, 0.0][None])[0, :2],
                               reference_corner_xy(on_press), atol=1e-9)
    assert not np.allclose(drawing.mark_mm, reference_corner_xy(drawing.cut_mm))


def test_a_flat_with_a_hole_has_two_net_loops(tmp_path):
    u, v = np.meshgrid(np.linspace(-1000, 1000, 21), np.linspace(-600, 600, 13), indexing="ij")
    xy = np.column_stack([u.ravel(), v.ravel()])
    index = np.arange(xy.shape[0]).reshape(21, 13)
    cells = [(i, j) for i in range(20) for j in range(12) if not (8 <= i < 12 and 4 <= j < 8)]
    faces = np.array([t for i, j in cells for t in ((index[i, j], index[i + 1, j], index[i + 1, j + 1]),
                                                   (index[i, j], index[i + 1, j + 1], index[i, j + 1]))])
    drawing = flat_drawing(xy, faces, 0.0)
    _, polylines = _read_back(write_flat_dxf(tmp_path / "hole.dxf", drawing))
    outer, hole = sorted(polylines["NET"], key=lambda p: -abs(area(p)))
    assert abs(area(outer)) == pytest.approx(2000 * 1200) and abs(area(hole)) == pytest.approx(400 * 400)
