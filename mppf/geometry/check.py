"""Checks that points can describe a plate: finite, enough of them, spread over an area."""

from __future__ import annotations

import math

import numpy as np

from mppf.core.errors import GeometryError
from mppf.core.transform import as_points

MAX_COORDINATE_MM = 1e9
"""Largest coordinate magnitude (1000 km) a plate may have; beyond it the unit or export is wrong."""


def check_plate(points, min_points: int, source: str = "points") -> np.ndarray:
    """Check that points can describe a plate; return them as an (n, 3) float array.

    Parameters
    ----------
    points : (n, 3) float, mm
    min_points : int
        Fewest points the caller needs (e.g. 16 for a bicubic fit).
    source : str
        Name used in messages (a file name).

    Raises
    ------
    GeometryError
        A coordinate beyond ``MAX_COORDINATE_MM``; too few points; all points
        coincident (spread below 1e-9 of the coordinate magnitude, at least 1e-9 mm);
        collinear (second principal spread below 1e-6 of the first).
    """
    pts = as_points(points, name=source)
    n = pts.shape[0]
    magnitude = float(np.abs(pts).max()) if pts.size else 0.0
    if magnitude > MAX_COORDINATE_MM:
        raise GeometryError(
            f"{source}: a coordinate of {magnitude:.3g} mm, beyond {MAX_COORDINATE_MM:.0e} mm",
            hint="check the file's unit (--units) and the export; plate coordinates are mm",
        )
    if n < min_points:
        raise GeometryError(
            f"{source}: {n} point(s), the fit needs at least {min_points}",
            hint="give more points or a lower degree",
        )
    if not np.all(np.isfinite(pts)):
        raise GeometryError(f"{source}: NaN or infinite coordinates", hint="repair the input")
    centred = pts - pts.mean(axis=0)
    spread = np.linalg.svd(centred, compute_uv=False) / math.sqrt(n)
    if spread[0] <= 1e-9 * max(magnitude, 1.0):
        raise GeometryError(
            f"{source}: all {n} points coincide (spread {spread[0]:.3g} mm)",
            hint="the plate has no extent; check the file and its units",
        )
    if spread[1] <= 1e-6 * spread[0]:
        raise GeometryError(
            f"{source}: the {n} points are collinear (spread {spread[0]:.3g} mm along a line, "
            f"{spread[1]:.3g} mm across)",
            hint="a plate needs points spread over an area",
        )
    return pts
