"""The correction aims the outer punch rows between their deviation and the edge's (mppf.correct.edge)."""

import numpy as np

from mppf.correct.edge import EDGE_FROM_RMS_MM, EDGE_SHARE, balanced_error


def test_balanced_error_moves_the_outer_rows_towards_the_edge_near_the_design():
    error = np.full((4, 4), 0.5)
    edge = np.full((4, 4), np.nan)
    edge[0] = -2.5
    out = balanced_error(error, edge)
    assert np.allclose(out[0], 0.5 + EDGE_SHARE * (-2.5 - 0.5))
    assert np.allclose(out[1:], 0.5)
    assert balanced_error(error, None) is not None and np.allclose(balanced_error(error, None), error)


def test_balanced_error_leaves_a_plate_far_off_as_it_is():
    error = np.full((4, 4), 2.0 * EDGE_FROM_RMS_MM)
    edge = np.full((4, 4), -5.0)
    assert np.allclose(balanced_error(error, edge), error)
