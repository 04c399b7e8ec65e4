"""The net plate's edge beyond the outer punch rows: balance what the punches cannot shape.

The strip between the last punch row and the net plate's edge follows the last punches
only as a whole: its kink (the second difference of the deviation across the strip) stays
the same from cycle to cycle to 0.1-0.2 mm, whatever the strokes (docs/correction.md).
Aimed at the punch values alone, the correction brings the last row to the design and
leaves the whole kink at the edge (K1: 2.5-3.7 mm at the net plate's corners, the RMS
already 0.5-0.7 mm). So, once the plate is near the design (punch RMS below
:data:`EDGE_FROM_RMS_MM`), the outer-row punches are aimed at the middle between their
own deviation and the edge's beyond them (:data:`EDGE_SHARE` of the way): the edge and
the last row then share the kink.
"""

from __future__ import annotations

import numpy as np


EDGE_SHARE = 0.5
"""Share of the way from a punch's own deviation to the edge's that its correction aims at."""

EDGE_FROM_RMS_MM = 2.0
"""Punch RMS deviation (mm) below which the edge counts (far off, the punches come first)."""


def balanced_error(error_mm, edge_mm) -> np.ndarray:
    """The deviation the correction aims to remove: the outer rows' moved towards the edge's.

    Parameters
    ----------
    error_mm : (rows, cols) float
        The deviation at the punches (NaN where unknown).
    edge_mm : (rows, cols) float or None
        :func:`mppf.measure.punches.edge_deviations` (None: unknown, the deviation is returned as it is).

    Returns
    -------
    (rows, cols) float
        ``error + EDGE_SHARE (edge - error)`` where the edge is known, once the punch RMS is
        below :data:`EDGE_FROM_RMS_MM`; else ``error``.
    """
    error = np.asarray(error_mm, dtype=float)
    if edge_mm is None:
        return error
    edge = np.asarray(edge_mm, dtype=float)
    finite = error[np.isfinite(error)]
    if finite.size == 0 or float(np.sqrt(np.mean(finite**2))) >= EDGE_FROM_RMS_MM:
        return error
    known = np.isfinite(edge) & np.isfinite(error)
    return np.where(known, error + EDGE_SHARE * (np.where(known, edge, 0.0) - error), error)
