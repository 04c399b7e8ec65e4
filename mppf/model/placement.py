"""Where to lay the plate: the corners of the plate as cut and its reference mark, in press mm.

:func:`placement_of` reads a job's :class:`~mppf.model.job_parts.PlateLayout` (the outline as
cut, the net outline, the margin, the reference mark) and keeps of each outline only its
corners (:func:`outline_corners`). Corner A is the corner of the cut plate the mark is on (the
mark is the corner of the plate as cut, the same corner as the cutter's DXF and the comparison),
the others follow counter-clockwise. The panel's "Lay the plate" view draws it
(:func:`mppf.panel.placement.bed_svg`), ``mppf press`` and ``mppf loop`` print it
(:mod:`mppf.cli._placement`): both take it from here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.model.job_parts import PlateLayout

MIN_TURN_DEG = 12.0
"""A vertex where the outline turns by less than this is not a corner (collinear points of the cut)."""

MAX_CORNERS = 12
"""At most this many corners are named (the sharpest)."""


def outline_corners(outline_mm, min_turn_deg: float = MIN_TURN_DEG, max_corners: int = MAX_CORNERS) -> np.ndarray:
    """The corners of a closed outline: its vertices where it turns by ``min_turn_deg`` or more.

    Vertices are dropped one at a time, the one of least turn first (its neighbours'
    turns recomputed), until every remaining vertex turns by at least ``min_turn_deg`` and
    at most ``max_corners`` remain (never fewer than 3). Every corner is a vertex of the
    outline, in the outline's order.

    Parameters
    ----------
    outline_mm : (k, 2) float
        A closed outline (the last vertex joins the first; a repeated first vertex is ignored).

    Returns
    -------
    (n, 2) float, 3 <= n <= max(3, min(k, max_corners))
    """
    pts = np.asarray(outline_mm, dtype=float).reshape(-1, 2)
    keep = [p for k, p in enumerate(pts) if k == 0 or np.linalg.norm(p - pts[k - 1]) > 1e-6]
    if len(keep) > 1 and np.linalg.norm(keep[0] - keep[-1]) <= 1e-6:
        keep.pop()
    while len(keep) > 3:
        turns = [_turn_deg(keep[k - 1], keep[k], keep[(k + 1) % len(keep)]) for k in range(len(keep))]
        k = int(np.argmin(turns))
        if turns[k] >= min_turn_deg and len(keep) <= max_corners:
            break
        keep.pop(k)
    return np.array(keep, dtype=float)


def _turn_deg(a, b, c) -> float:
    """How much the path a -> b -> c turns at b (degrees, 0 = straight on)."""
    u, v = b - a, c - b
    nu, nv = np.linalg.norm(u), np.linalg.norm(v)
    if nu < 1e-9 or nv < 1e-9:
        return 0.0
    return float(np.degrees(np.arccos(np.clip(np.dot(u, v) / (nu * nv), -1.0, 1.0))))


@dataclass(frozen=True, eq=False)
class Placement:
    """Where the plate goes on the bed (press mm).

    Attributes
    ----------
    cut_corners_mm : (n, 2) float
        Corners of the plate as cut (with the margin), corner A (nearest the mark) first,
        counter-clockwise.
    net_corners_mm : (m, 2) float
        Corners of the net outline (the plate after trimming).
    mark_mm : (2,) float
        The reference mark: on the corner of the plate as cut (corner A, the cut outline's
        corner nearest punch R1 C1; :attr:`mppf.model.job_parts.PlateLayout.reference_corner_mm`).
    margin_mm : float
    cut_outline_mm, net_outline_mm : (k, 2) float
        The full outlines, for drawing.
    """

    cut_corners_mm: np.ndarray
    net_corners_mm: np.ndarray
    mark_mm: np.ndarray
    margin_mm: float
    cut_outline_mm: np.ndarray
    net_outline_mm: np.ndarray

    @property
    def corner_names(self) -> list[str]:
        """"A", "B", ... for :attr:`cut_corners_mm`."""
        return [chr(ord("A") + k) for k in range(len(self.cut_corners_mm))]

    def rows(self) -> list[dict]:
        """One dict per cut corner: ``name``, ``x_mm``, ``y_mm``, ``mark`` (True for corner A)."""
        return [{"name": n, "x_mm": float(x), "y_mm": float(y), "mark": k == 0}
                for k, (n, (x, y)) in enumerate(zip(self.corner_names, self.cut_corners_mm))]


def placement_of(layout: PlateLayout) -> Placement:
    """The corners of a job's plate layout, corner A nearest the reference mark."""
    cut = outline_corners(layout.outline_mm)
    first = int(np.argmin(np.linalg.norm(cut - layout.reference_corner_mm, axis=1)))
    return Placement(
        cut_corners_mm=np.roll(cut, -first, axis=0),
        net_corners_mm=outline_corners(layout.net_outline_mm),
        mark_mm=np.asarray(layout.reference_corner_mm, dtype=float),
        margin_mm=float(layout.margin_mm),
        cut_outline_mm=layout.outline_mm,
        net_outline_mm=layout.net_outline_mm,
    )
