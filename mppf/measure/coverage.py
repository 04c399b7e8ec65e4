"""Coverage: which parts of the net plate a comparison did not measure (occlusions, rim bands without points).

A plate cannot be passed on what was not measured: the worst spot of a formed plate is often
hidden (a clamp, a shadow) or on the rim the scanner missed. So ``compare`` reports every
area of the net plate that holds an empty disc wider than the **allowed gap** (``docs/compare.md``,
"Coverage"):

1. A square grid over the net outline (the design's convex outline, design frame (u, v)),
   cells of :data:`CELL_GAPS` of the allowed gap or finer; at each cell the distance ``r``
   to the nearest measured point (the plate's and the trim margin's points, not the
   outside ones: the k-d tree of the artefact test) and the distance ``b`` to the outline.
2. The largest empty disc inside the plate centred at a cell has the radius ``min(r, b)``.
   Cells where that is more than half the allowed gap centre gaps; the uncovered area is
   the union of those gaps' discs (a distance transform), split into connected regions
   (``scipy.ndimage.label``).
3. Each region is reported: centroid and bounding box (u, v), area, its largest gap (the
   widest empty disc, mm across), whether it reaches the rim, and on the press the nearest
   punch.

The allowed gap: the measurement's own gaps between its points are not holes. It is
``max(gap_mm, GAP_SPACINGS x the point spacing)``, at most ``max_gap_mm``:

- ``gap_mm`` (default :data:`GAP_MM`): below it no shape error a press makes can hide, its
  flanks reach measured points (a dent of a press is a punch pitch or more across: 150 mm
  on the example press);
- :data:`GAP_SPACINGS` point spacings: the largest gaps a measurement has between its own
  points (a regular grid 1.5 spacings across, a jittered scanner grid 2.3, randomly placed
  points up to 4.3; measured) stay below it: a sparse grid of a few hundred points is not
  flagged between its points, a missing block of them is;
- ``max_gap_mm`` (default :data:`MAX_GAP_MM`, two punch pitches): no measurement, however
  sparse, passes a plate with a wider gap: a whole punch's error could hide in it. A grid
  coarser than about ``max_gap_mm / 1.5`` is flagged everywhere (too sparse to pass).

Lengths in mm, areas in mm^2.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.errors import InputError
from mppf.core.polygon import contains, convex_inset
from mppf.core.validate import check_positive

GAP_MM = 100.0
"""Default smallest allowed gap (mm across; see the module docstring)."""

MAX_GAP_MM = 300.0
"""Default largest allowed gap (mm across), whatever the point spacing."""

GAP_SPACINGS = 5.0
"""The allowed gap is at least this many point spacings (the measurement's own gaps stay below it)."""

CELL_GAPS = 1.0 / 8.0
"""Grid cell size, in allowed gaps (the gaps' sizes are found within about a cell)."""

MAX_CELLS = 250000
"""Most grid cells over the net plate (a coarser grid above)."""

LISTED = 50
"""Regions written in full in the JSON (the largest first; the count is always given)."""


@dataclass(frozen=True)
class Gap:
    """An uncovered region of the net plate.

    Attributes
    ----------
    centroid_uv_mm : (2,) float
    box_uv_mm : (4,) float
        Bounding box ``u_min, v_min, u_max, v_max``.
    area_mm2 : float
    gap_mm : float
        Its largest empty disc inside the plate, across.
    on_rim : bool
        It reaches the net outline.
    press_xy_mm : (2,) float or None
        The centroid on the press (when the press pose is known).
    punch : str or None
        The punch nearest to it.
    """

    centroid_uv_mm: tuple
    box_uv_mm: tuple
    area_mm2: float
    gap_mm: float
    on_rim: bool
    press_xy_mm: tuple | None = None
    punch: str | None = None

    def describe(self) -> str:
        """One line: size, where."""
        where = f"u, v = {self.centroid_uv_mm[0]:.0f}, {self.centroid_uv_mm[1]:.0f} mm"
        if self.punch:
            where += f", near punch {self.punch}"
        rim = " on the rim" if self.on_rim else ""
        return f"{self.area_mm2 / 1e6:.3f} m^2{rim} at {where} (gap {self.gap_mm:.0f} mm across)"

    def to_dict(self) -> dict:
        return {"centroid_uv_mm": [float(v) for v in self.centroid_uv_mm],
                "box_uv_mm": [float(v) for v in self.box_uv_mm], "area_mm2": self.area_mm2, "gap_mm": self.gap_mm,
                "on_rim": self.on_rim,
                "press_xy_mm": None if self.press_xy_mm is None else [float(v) for v in self.press_xy_mm],
                "punch": self.punch}


@dataclass(frozen=True, eq=False)
class Coverage:
    """What of the net plate was measured (``Comparison.coverage``).

    Attributes
    ----------
    allowed_gap_mm : float
        The gap the verdict allows (see the module docstring).
    gap_mm, max_gap_mm : float
        The options it came from.
    spacing_mm : float
        The measurement's median point spacing.
    largest_gap_mm : float
        The widest empty disc anywhere inside the net plate, across.
    uncovered_pct : float
        Share of the net plate's area in the regions.
    regions : tuple of Gap
        Largest first.
    grid_u_mm, grid_v_mm : (nu,), (nv,) float
        The cell centres' u and v.
    uncovered : (nv, nu) bool
        The uncovered cells (for pictures).
    """

    allowed_gap_mm: float
    gap_mm: float
    max_gap_mm: float
    spacing_mm: float
    largest_gap_mm: float
    uncovered_pct: float
    regions: tuple
    grid_u_mm: np.ndarray
    grid_v_mm: np.ndarray
    uncovered: np.ndarray

    @property
    def complete(self) -> bool:
        """No region: the whole net plate measured within the allowed gap."""
        return not self.regions

    def names(self, count: int = 3) -> tuple[str, ...]:
        """The largest regions in words (for the headline)."""
        return tuple(g.describe() for g in self.regions[:count])

    def describe(self) -> str:
        """One line for the notes."""
        head = (f"coverage: allowed gap {self.allowed_gap_mm:.0f} mm across (max of {self.gap_mm:g} mm and "
                f"{GAP_SPACINGS:g} x the point spacing {self.spacing_mm:.1f} mm, at most {self.max_gap_mm:g} mm); "
                f"largest gap in the net plate {self.largest_gap_mm:.0f} mm")
        if self.complete:
            return f"{head}: the whole net plate is measured"
        more = len(self.regions) - 3
        listed = "; ".join(self.names()) + (f"; and {more} more" if more > 0 else "")
        return (f"{head}: {len(self.regions)} area(s) not measured ({self.uncovered_pct:.1f} % of the net plate): "
                f"{listed}")

    def to_dict(self) -> dict:
        """JSON-able: the rule, the largest gap, the regions (the largest :data:`LISTED`)."""
        return {"allowed_gap_mm": self.allowed_gap_mm, "gap_mm": self.gap_mm, "max_gap_mm": self.max_gap_mm,
                "gap_spacings": GAP_SPACINGS, "spacing_mm": self.spacing_mm, "largest_gap_mm": self.largest_gap_mm,
                "complete": self.complete, "uncovered_pct": self.uncovered_pct, "n_regions": len(self.regions),
                "regions": [g.to_dict() for g in self.regions[:LISTED]]}


def check_gaps(gap_mm, max_gap_mm) -> tuple[float, float]:
    """The smallest and the largest allowed gap as floats; InputError unless positive and in order."""
    gap_mm = float(check_positive("allowed gap", gap_mm, unit="mm"))
    max_gap_mm = float(check_positive("largest allowed gap", max_gap_mm, unit="mm"))
    if max_gap_mm < gap_mm:
        raise InputError(f"the largest allowed gap ({max_gap_mm:g} mm) is below the allowed gap ({gap_mm:g} mm)",
                         hint="give a largest gap at least as wide as the gap")
    return gap_mm, max_gap_mm


def allowed_gap_mm(spacing_mm: float, gap_mm: float = GAP_MM, max_gap_mm: float = MAX_GAP_MM) -> float:
    """The allowed gap (mm across): ``max(gap_mm, GAP_SPACINGS x spacing)``, at most ``max_gap_mm``."""
    spacing = float(spacing_mm) if np.isfinite(spacing_mm) else 0.0
    return float(min(max(gap_mm, GAP_SPACINGS * spacing), max_gap_mm))


def coverage(outline_uv: np.ndarray, nearest_mm, spacing_mm: float, gap_mm: float = GAP_MM,
             max_gap_mm: float = MAX_GAP_MM, where=None) -> Coverage:
    """The coverage of the net plate (see the module docstring).

    Parameters
    ----------
    outline_uv : (k, 2) float, mm
        The net plate's convex outline in the design frame.
    nearest_mm : callable
        ``nearest_mm(cells (c, 2)) -> (c,)``: distance from each position to the nearest
        measured point (a k-d tree's query).
    spacing_mm : float
        The measurement's median point spacing.
    gap_mm, max_gap_mm : float
        The smallest and the largest allowed gap (mm across).
    where : callable, optional
        ``where(uv (2,)) -> (press_xy (2,), punch name)`` for the regions (the press pose).

    Raises
    ------
    InputError
        A gap option that is not a positive number, or ``max_gap_mm < gap_mm``.
    """
    from scipy import ndimage

    gap_mm, max_gap_mm = check_gaps(gap_mm, max_gap_mm)
    allowed = allowed_gap_mm(spacing_mm, gap_mm, max_gap_mm)
    # 1. the grid over the net outline: distance to the nearest measured point and to the outline
    lo, hi = outline_uv.min(axis=0), outline_uv.max(axis=0)
    cell = max(CELL_GAPS * allowed, float(np.sqrt(np.prod(hi - lo) / MAX_CELLS)))
    gu = np.arange(lo[0] + cell / 2, hi[0], cell) if hi[0] - lo[0] > cell else np.array([(lo[0] + hi[0]) / 2])
    gv = np.arange(lo[1] + cell / 2, hi[1], cell) if hi[1] - lo[1] > cell else np.array([(lo[1] + hi[1]) / 2])
    uu, vv = np.meshgrid(gu, gv)
    cells = np.column_stack([uu.ravel(), vv.ravel()])
    inside = contains(outline_uv, cells)
    empty = np.zeros(cells.shape[0])  # the radius of the largest empty disc inside the plate centred at the cell
    empty[inside] = np.minimum(nearest_mm(cells[inside]), np.maximum(convex_inset(outline_uv, cells[inside]), 0.0))
    empty = empty.reshape(uu.shape)
    inside = inside.reshape(uu.shape)
    # 2. gaps: cells centring an empty disc wider than allowed; the uncovered area is the union of their discs
    centres = inside & (2.0 * empty > allowed)
    uncovered = inside & (ndimage.distance_transform_edt(~centres) * cell <= allowed / 2.0) if centres.any() \
        else np.zeros_like(inside)
    # 3. the regions, largest first
    labels, count = ndimage.label(uncovered, structure=np.ones((3, 3)))
    rim = inside & ~ndimage.binary_erosion(inside, structure=np.ones((3, 3)), border_value=0)
    regions = [_region(labels == i, uu, vv, empty, rim, cell, where) for i in range(1, count + 1)]
    regions.sort(key=lambda g: -g.area_mm2)
    share = 100.0 * float(uncovered.sum()) / max(int(inside.sum()), 1)
    largest = 2.0 * float(empty[inside].max()) if inside.any() else 0.0
    return Coverage(allowed, float(gap_mm), float(max_gap_mm), float(spacing_mm), largest, share, tuple(regions),
                    gu, gv, uncovered)


def _region(mask, uu, vv, empty, rim, cell: float, where) -> Gap:
    """The report of one uncovered region (a boolean mask of the grid)."""
    u, v = uu[mask], vv[mask]
    centroid = (float(u.mean()), float(v.mean()))
    box = (float(u.min() - cell / 2), float(v.min() - cell / 2), float(u.max() + cell / 2), float(v.max() + cell / 2))
    press_xy = punch = None
    if where is not None:
        press_xy, punch = where(np.asarray(centroid))
        press_xy = tuple(float(c) for c in press_xy)
    return Gap(centroid, box, float(mask.sum()) * cell * cell, 2.0 * float(empty[mask].max()),
               bool((mask & rim).any()), press_xy, punch)
