"""A plate cut from a hull model: its region in hull coordinates, sampled on the exact surface.

A shell plate is bounded by seams (along the ship) and butts (across it). Its region is given
in hull coordinates (mm, full scale) in one of two ways:

* :class:`ProjectedRegion`: a polygon in the two coordinates other than an axis, seen from
  one side of that axis (the plate as drawn on the profile, ``+y``; the body plan, ``+x``;
  or the bottom view, ``-z``); the plate is the part of the hull the polygon covers,
  the hull nearest the viewer where it is seen twice;
* :class:`GirthRegion`: bounds on x (the butts) and on the girth from the keel
  (the seams), as on the shell expansion (:mod:`mppf.geometry.stations`).

:func:`extract_plate` samples the region on a grid at a spacing (the polygon's bounding box
in its plane, or stations x girths), every point on the exact CAD surface, and gives the
grid's triangles; the triangles' largest deviation from the surface is measured.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.errors import GeometryError, InputError
from mppf.core.polygon import as_polygon, contains
from mppf.core.validate import check_positive
from mppf.geometry.cad import CadModel
from mppf.geometry.cad_query import closest_points, intersect_lines

AXES = {"x": 0, "y": 1, "z": 2}
MAX_POINTS = 4_000_000
"""Largest grid sampled (points)."""


@dataclass(frozen=True)
class ProjectedRegion:
    """A plate outline seen along a hull axis.

    Attributes
    ----------
    polygon_mm : (k, 2) float
        Corners in the two other coordinates, in order (x, z for ``y``; y, z for ``x``; x, y for ``z``).
    seen_from : str
        ``"+y"``, ``"-z"``, ...: the axis and the side the plate is seen from.
    """

    polygon_mm: np.ndarray
    seen_from: str = "+y"


@dataclass(frozen=True)
class GirthRegion:
    """A plate between two stations (butts) and two girths from the keel (seams), mm."""

    x_mm: tuple[float, float]
    girth_mm: tuple[float, float]


@dataclass(frozen=True, eq=False)
class ExtractedPlate:
    """A plate sampled from a hull model.

    Attributes
    ----------
    points : (n, 3) float, mm
        Hull coordinates, row by row of the grid (points outside a polygon left out).
    grid_shape : (2,) int
        Rows and columns of the full grid (x stations by girths, or the polygon's box).
    grid_index : (n, 2) int
        Row and column of each point.
    faces : (m, 3) int
        Triangles of the grid cells whose four corners are points.
    size_mm : (2,) float
        Length along the grid's rows and columns, measured on the surface (median over lines).
    area_mm2 : float
        Area of the triangles.
    chord_mm : float
        Largest distance of a triangle's centroid from the surface.
    """

    points: np.ndarray
    grid_shape: tuple[int, int]
    grid_index: np.ndarray
    faces: np.ndarray
    size_mm: np.ndarray
    area_mm2: float
    chord_mm: float


def extract_plate(model: CadModel, region, spacing_mm: float) -> ExtractedPlate:
    """Sample a plate of a hull model on a grid at ``spacing_mm``.

    Raises
    ------
    InputError
        A bad spacing, region or a grid larger than :data:`MAX_POINTS`.
    GeometryError
        Grid points that do not meet the hull (a region off the model, a wrong axis or scale).
    """
    spacing = check_positive("the spacing", spacing_mm, unit="mm", hint="give e.g. --spacing 50")
    # 1. the grid on the exact surface
    if isinstance(region, GirthRegion):
        grid, inside = _girth_grid(model, region, spacing)
    else:
        grid, inside = _projected_grid(model, region, spacing)
    # 2. the grid's triangles, their area, their largest deviation from the surface
    rows, cols = grid.shape[:2]
    number = np.full((rows, cols), -1)
    number[inside] = np.arange(int(inside.sum()))
    faces = _cell_triangles(number)
    points = grid[inside]
    return ExtractedPlate(points=points, grid_shape=(rows, cols), grid_index=np.argwhere(inside), faces=faces,
                          size_mm=_size(grid), area_mm2=_area(points, faces),
                          chord_mm=_chord(model, points, faces))


def _girth_grid(model: CadModel, region: GirthRegion, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    from mppf.geometry.stations import sample_girth

    (x0, x1), (g0, g1) = sorted(region.x_mm), sorted(region.girth_mm)
    if g0 < 0:
        raise InputError(f"girths are measured from the keel and cannot be negative, got {g0:g} mm",
                         hint="give --girth G0 G1 with 0 <= G0 < G1 (mm at full scale)")
    x = _span(x0, x1, spacing, "x")
    girth = _span(g0, g1, spacing, "girth")
    _check_size(x.size * girth.size)
    grid = sample_girth(model, x, girth)
    return grid, np.ones(grid.shape[:2], dtype=bool)


def _projected_grid(model: CadModel, region: ProjectedRegion, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    axis, side = _axis(region.seen_from)
    other = [k for k in range(3) if k != axis]
    polygon = as_polygon(region.polygon_mm, "the plate's polygon")
    lo, hi = polygon.min(axis=0), polygon.max(axis=0)
    a, b = _span(lo[0], hi[0], spacing, "the polygon"), _span(lo[1], hi[1], spacing, "the polygon")
    _check_size(a.size * b.size)
    plane = np.stack(np.meshgrid(a, b, indexing="ij"), axis=-1)
    inside = contains(polygon, plane.reshape(-1, 2), tolerance_mm=1e-6 * spacing).reshape(plane.shape[:2])
    origins = np.zeros((inside.sum(), 3))
    origins[:, other] = plane[inside]
    origins[:, axis] = model.bounds_mm[:, axis].mean()
    direction = np.eye(3)[axis]
    hits = intersect_lines(model, origins, direction, seen_from=side * direction)
    if not hits.found.all():
        miss = origins[~hits.found][0][other]
        names = "".join("xyz"[k] for k in other)
        raise GeometryError(
            f"{int((~hits.found).sum())} of {hits.found.size} grid points of the region do not meet the hull "
            f"seen from {region.seen_from} (the first at {names[0]} = {miss[0]:.0f}, {names[1]} = {miss[1]:.0f} mm)",
            hint="give the polygon in full-scale hull coordinates (mm; --scale for a model-scale file) "
                 "inside the hull's outline seen from that side")
    grid = np.full(plane.shape[:2] + (3,), np.nan)
    grid[inside] = hits.points_mm
    return grid, inside


def _axis(seen_from: str) -> tuple[int, float]:
    text = str(seen_from).strip().lower()
    if len(text) != 2 or text[0] not in "+-" or text[1] not in AXES:
        raise InputError(f"the view must be a signed hull axis like +y or -z, got {seen_from!r}",
                         hint="give --seen-from +y (the side shell), -z (the bottom) or +x / -x")
    return AXES[text[1]], (1.0 if text[0] == "+" else -1.0)


def _span(low: float, high: float, spacing: float, name: str) -> np.ndarray:
    """Equally spaced values from ``low`` to ``high``, as near ``spacing`` apart as fits exactly."""
    if not (np.isfinite(low) and np.isfinite(high)) or high <= low:
        raise InputError(f"{name} must span a length, got {low:g} .. {high:g} mm",
                         hint="give the lower bound first and a larger upper bound")
    return np.linspace(low, high, int(np.ceil((high - low) / spacing - 1e-9)) + 1)


def _check_size(n: int) -> None:
    if n > MAX_POINTS:
        raise InputError(f"the grid would have {n:,} points (more than {MAX_POINTS:,})",
                         hint="give a larger --spacing or a smaller region")


def _cell_triangles(number: np.ndarray) -> np.ndarray:
    """Two triangles (counter-clockwise in (row, col)) per grid cell whose four corners exist."""
    a, b = number[:-1, :-1], number[1:, :-1]
    c, d = number[1:, 1:], number[:-1, 1:]
    full = (a >= 0) & (b >= 0) & (c >= 0) & (d >= 0)
    first = np.column_stack([a[full], b[full], c[full]])
    second = np.column_stack([a[full], c[full], d[full]])
    return np.vstack([first, second]).astype(np.int64)


def _size(grid: np.ndarray) -> np.ndarray:
    """Median length of the grid lines along rows and along columns (on the surface)."""
    lengths = []
    for axis in (0, 1):
        steps = np.linalg.norm(np.diff(grid, axis=axis), axis=2)  # NaN next to a point outside
        line = np.where(np.isfinite(steps), steps, 0.0).sum(axis=axis)
        lengths.append(float(np.median(line[line > 0])) if np.any(line > 0) else 0.0)
    return np.array(lengths)


def _area(points: np.ndarray, faces: np.ndarray) -> float:
    if faces.size == 0:
        return 0.0
    p = points[faces]
    return float(0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum())


def _chord(model: CadModel, points: np.ndarray, faces: np.ndarray) -> float:
    """Largest distance of a triangle centroid from the surface, mm."""
    if faces.size == 0:
        return 0.0
    hits = closest_points(model, points[faces].mean(axis=1))
    return float(np.nanmax(hits.distance_mm))
