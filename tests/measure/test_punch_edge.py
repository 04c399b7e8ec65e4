"""The net plate's edge beyond the outer punch rows, measured (mppf.measure.punches.edge_deviations)."""

import numpy as np

from mppf.measure.punches import edge_deviations

PX = np.array([-225.0, -75.0, 75.0, 225.0])  # 4 columns, pitch 150
PY = np.array([-225.0, -75.0, 75.0, 225.0])  # 4 rows


def _net(kink_mm: float):
    """Net plate points on a 50 mm grid over +-250 mm; the edge rows at y = +-250 deviate by ``kink_mm``."""
    x, y = np.meshgrid(np.arange(-250.0, 251.0, 50.0), np.arange(-250.0, 251.0, 50.0))
    xy = np.column_stack([x.ravel(), y.ravel()])
    dev = np.where(np.abs(xy[:, 1]) > 249.0, kink_mm, 0.0) + 0.001 * xy[:, 0]
    return xy, dev


def test_edge_deviations_takes_the_edge_beyond_the_first_and_last_row_of_each_column():
    active = np.ones((4, 4), dtype=bool)
    active[:, 0] = [False, True, True, True]  # column 0 starts one row later
    xy, dev = _net(-3.0)
    edge = edge_deviations(PX, PY, active, xy, dev)
    outer = np.zeros((4, 4), dtype=bool)
    outer[[0, 3], 1:] = True
    outer[[1, 3], 0] = True
    assert np.all(np.isfinite(edge[outer]))
    assert np.all(np.isnan(edge[~outer]))
    # the top and bottom edges are at -3 mm (plus the small x slope of the points near the column)
    assert np.allclose(edge[3, 1:], -3.0 + 0.001 * np.array([-75.0, 75.0, 225.0]), atol=0.06)
    # column 0's first active row is at y = -75: the edge beyond it (y <= -75 - 150) is not within one pitch
    # of the net edge at -250 but the x-edge points between -225 and -75 are: they count, the kink does not
    assert edge[1, 0] > -3.0


def test_edge_deviations_is_nan_without_points():
    edge = edge_deviations(PX, PY, np.ones((4, 4), dtype=bool), np.zeros((0, 2)), np.zeros(0))
    assert np.all(np.isnan(edge))


def test_a_comparison_measures_the_curl_of_the_net_edge_beyond_the_outer_rows():
    import margin_helpers as mh
    from mppf.core.transform import apply_tf, invert_tf
    from mppf.measure.compare import compare
    from mppf.measure.options import CompareOptions

    u, v, scan = mh.scan(n=30000, seed=3)
    net = ~mh.band(u, v)
    # the plate curls up over the last 40 mm beyond the outer row at v = +960, up to 2 mm at the edge v = +1000
    local = apply_tf(invert_tf(mh.pose()), scan[net])
    curl = 2.0 * np.clip((v[net] - 960.0) / 40.0, 0.0, 1.0) ** 2
    curled = apply_tf(mh.pose(), local + curl[:, None] * mh.normals(u[net], v[net]))
    px, py = np.meshgrid(np.arange(-1440.0, 1441.0, 120.0), np.arange(-960.0, 961.0, 80.0))
    c = compare(mh.design(), curled, CompareOptions(tf_press_design=np.eye(4), punch_xy_mm=np.stack([px, py], axis=-1)))
    edge = c.punch_edge_mm
    assert edge.shape == px.shape
    assert np.all(np.isnan(edge[1:-1]))  # only the outer rows have an edge beyond them
    # the curled edge, seen beyond the columns (a column without a random point in the 5 mm edge band has none)
    assert np.isfinite(edge[-1]).mean() > 0.8 and np.nanmin(edge[-1, 1:-1]) > 1.0
    assert np.nanmax(np.abs(edge[0])) < 0.5  # the straight edge
    assert np.max(np.abs(c.punch_deviation_mm[:-2])) < 0.5  # the punches themselves barely see it
    assert len(c.to_dict()["punch_edge_mm"]) == px.shape[0]
