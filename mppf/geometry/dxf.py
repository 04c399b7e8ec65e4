"""The flat plate for the NC cutter: a DXF drawing (``ezdxf``) in the flat's coordinates, mm.

Layers (see ``docs/file-formats.md``, "Flat plate for the NC cutter"):

=========  ======================================================================
``CUT``    the outline the plate is cut along: the net outline grown by the trim margin
           (the convex outline grown with mitred corners, as the planner lays it on the
           press; with no margin, the net outline itself)
``NET``    the net outline: the boundary of the unfolded plate (the design's edge)
``MARK``   the reference mark: a point on the reference corner of the cut outline and
           a circle with a cross just inside it; a plate formed in sections also has each
           section's two placement marks (a point with a cross)
``TEXT``   ``REF`` beside the mark; the plate's name, size and margin at its centre; the
           section marks' names (``2a``, ``2b``: section 2's marks)
``PUNCH``  optional: the punch centres of a job (circles), in the flat's coordinates
=========  ======================================================================

The reference corner is the corner of the plate as cut (margin included) with the
smallest x + y in the coordinates it is laid on the press in
(:func:`mppf.model.job_parts.reference_corner_xy`): the corner at the press's first punch
(row 1, column 1). The drawing is in the flat's own coordinates ($INSUNITS 4, mm).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mppf.core.errors import GeometryError, InputError
from mppf.core.polygon import area, convex_outline, offset_convex
from mppf.core.transform import apply_tf, invert_tf
from mppf.geometry.mesh import boundary_edges
from mppf.model.job_parts import reference_corner_xy

LAYERS = {"CUT": 1, "NET": 3, "MARK": 5, "TEXT": 7, "PUNCH": 4}
"""Layer names and their AutoCAD colour index (red, green, blue, white, cyan)."""

MARK_INSET_MM = 40.0
"""The mark's circle lies this far inside the reference corner, along its bisector."""

MARK_RADIUS_MM = 10.0
TEXT_HEIGHT_MM = 40.0
PUNCH_RADIUS_MM = 8.0


@dataclass(frozen=True, eq=False)
class FlatDrawing:
    """What the cutter's drawing of a flat plate holds (mm, the flat's coordinates).

    Attributes
    ----------
    cut_mm : (k, 2) float
        The outline as cut, counter-clockwise.
    net_mm : tuple of (j, 2) float
        The net outline (the first and largest loop) and any holes.
    margin_mm : float
    mark_mm : (2,) float
        The reference corner (a corner of ``cut_mm``).
    mark_centre_mm : (2,) float
        Where the mark's circle goes, just inside the corner.
    punches_mm : (p, 2) float
        Punch centres to mark (may be empty).
    label : str
    section_marks : tuple of (str, (2,) float)
        A plate formed in sections: each section's placement marks, named ("2a", "2b":
        section 2's two marks, as the placement instruction names them) and where they lie on the flat (empty otherwise).
    """

    cut_mm: np.ndarray
    net_mm: tuple
    margin_mm: float
    mark_mm: np.ndarray
    mark_centre_mm: np.ndarray
    punches_mm: np.ndarray
    label: str = ""
    section_marks: tuple = ()


def flat_drawing(flat_xy, faces, margin_mm: float, *, tf_press_flat=None, punches_press_mm=None,
                 label: str = "", section_marks=()) -> FlatDrawing:
    """The cut and net outlines, the reference mark and punch marks of an unfolded plate.

    Parameters
    ----------
    flat_xy : (n, 2) float, mm
        The flat plate (z = 0 dropped).
    faces : (m, 3) int
        Its triangles (the unfolding's): their boundary is the net outline.
    margin_mm : float
        Trim margin (>= 0).
    tf_press_flat : (4, 4) float, optional
        How the flat lies on the press (a job's); the reference corner is taken there.
        Default: as the planner lays a flat from ``mppf unfold``, its axes along the press's.
    punches_press_mm : (p, 2) float, optional
        Punch axes on the press to mark (needs ``tf_press_flat``).
    label : str
    section_marks : sequence of (str, (2,) float), optional
        Named placement marks of a sectional job, in the flat's coordinates
        (:func:`section_marks_of`).
    """
    xy = np.asarray(flat_xy, dtype=float)[:, :2]
    if not (np.isfinite(margin_mm) and margin_mm >= 0):
        raise InputError(f"the trim margin must be 0 mm or more, got {margin_mm!r}", hint="give e.g. --margin 100")
    # 1. the net outline: the boundary loops of the unfolded triangles, the largest first, counter-clockwise
    loops = sorted((xy[loop] for loop in _boundary_loops(faces)), key=lambda p: -abs(area(p)))
    loops = [loop if area(loop) > 0 else loop[::-1] for loop in loops]
    # 2. the cut outline: grown by the margin (the convex outline, as the planner lays it)
    cut = offset_convex(convex_outline(loops[0], "the flat plate"), margin_mm) if margin_mm > 0 else loops[0]
    # 3. the reference corner: smallest x + y where the plate lies on the press
    tf = np.eye(4) if tf_press_flat is None else np.asarray(tf_press_flat, dtype=float)
    on_press = apply_tf(tf, np.column_stack([cut, np.zeros(len(cut))]))[:, :2]
    corner = int(np.flatnonzero(np.all(on_press == reference_corner_xy(on_press), axis=1))[0])
    # 4. punch centres in the flat's coordinates, inside the cut outline
    punches = np.empty((0, 2))
    if punches_press_mm is not None:
        p = np.asarray(punches_press_mm, dtype=float).reshape(-1, 2)
        punches = apply_tf(invert_tf(tf), np.column_stack([p, np.zeros(len(p))]))[:, :2]
    marks = tuple((str(name), np.asarray(xy, dtype=float)[:2].copy()) for name, xy in section_marks)
    return FlatDrawing(cut_mm=cut, net_mm=tuple(loops), margin_mm=float(margin_mm), mark_mm=cut[corner].copy(),
                       mark_centre_mm=_inside_corner(cut, corner, MARK_INSET_MM), punches_mm=punches, label=label,
                       section_marks=marks)


def section_marks_of(job) -> list[tuple[str, np.ndarray]]:
    """The placement marks of a job planned in sections, named "<section>a" and "<section>b" as the placement instruction names them
    (:func:`mppf.planning.sections.placement_text`), on its flat (mm).

    ``job.sections[k].marks_flat_mm`` are in the coordinates of the flat file the job was
    planned from (the flat of ``mppf unfold``); a job in one piece has none.
    """
    return [(f"{s.index}{'ab'[k]}", np.asarray(s.marks_flat_mm, dtype=float)[k, :2])
            for s in (job.sections or []) for k in range(len(s.marks_flat_mm))]


def write_flat_dxf(path, drawing: FlatDrawing) -> Path:
    """Write ``drawing`` as a DXF R2010 file in mm; ezdxf's audit must find no error.

    Raises
    ------
    InputError
        The file cannot be written, or the audit finds an error (a bug: nothing is written).
    """
    import ezdxf
    from ezdxf.enums import TextEntityAlignment

    path = Path(path)
    doc = ezdxf.new("R2010", setup=False, units=4)  # 4: millimetres ($INSUNITS; $MEASUREMENT metric)
    for name, colour in LAYERS.items():
        doc.layers.add(name, color=colour)
    msp = doc.modelspace()
    # 1. outlines
    msp.add_lwpolyline(_xy(drawing.cut_mm), format="xy", close=True, dxfattribs={"layer": "CUT"})
    for loop in drawing.net_mm:
        msp.add_lwpolyline(_xy(loop), format="xy", close=True, dxfattribs={"layer": "NET"})
    # 2. the reference mark and its text
    corner, centre = tuple(map(float, drawing.mark_mm)), tuple(map(float, drawing.mark_centre_mm))
    msp.add_point(corner, dxfattribs={"layer": "MARK"})
    msp.add_circle(centre, MARK_RADIUS_MM, dxfattribs={"layer": "MARK"})
    for dx, dy in ((1.0, 0.0), (0.0, 1.0)):
        msp.add_line((centre[0] - 1.5 * MARK_RADIUS_MM * dx, centre[1] - 1.5 * MARK_RADIUS_MM * dy),
                     (centre[0] + 1.5 * MARK_RADIUS_MM * dx, centre[1] + 1.5 * MARK_RADIUS_MM * dy),
                     dxfattribs={"layer": "MARK"})
    inward = np.asarray(centre) - np.asarray(corner)
    inward /= max(float(np.linalg.norm(inward)), 1e-12)
    ref = np.asarray(centre) + inward * 2.5 * TEXT_HEIGHT_MM
    msp.add_text("REF", height=TEXT_HEIGHT_MM, dxfattribs={"layer": "TEXT"}).set_placement(
        tuple(map(float, ref)), align=TextEntityAlignment.MIDDLE_CENTER)
    if drawing.label:
        middle = tuple(map(float, 0.5 * (drawing.cut_mm.min(axis=0) + drawing.cut_mm.max(axis=0))))
        msp.add_text(drawing.label, height=TEXT_HEIGHT_MM, dxfattribs={"layer": "TEXT"}).set_placement(
            middle, align=TextEntityAlignment.MIDDLE_CENTER)
    # 3. punch centres
    for x, y in drawing.punches_mm:
        msp.add_circle((float(x), float(y)), PUNCH_RADIUS_MM, dxfattribs={"layer": "PUNCH"})
    # 4. the placement marks of the sections: a point, a cross and its name
    for name, (x, y) in drawing.section_marks:
        msp.add_point((float(x), float(y)), dxfattribs={"layer": "MARK"})
        for dx, dy in ((1.0, 0.0), (0.0, 1.0)):
            msp.add_line((x - 1.5 * MARK_RADIUS_MM * dx, y - 1.5 * MARK_RADIUS_MM * dy),
                         (x + 1.5 * MARK_RADIUS_MM * dx, y + 1.5 * MARK_RADIUS_MM * dy), dxfattribs={"layer": "MARK"})
        msp.add_text(name, height=TEXT_HEIGHT_MM / 2, dxfattribs={"layer": "TEXT"}).set_placement(
            (float(x) + 2 * MARK_RADIUS_MM, float(y) + 2 * MARK_RADIUS_MM), align=TextEntityAlignment.BOTTOM_LEFT)
    # 5. audit, then write
    auditor = doc.audit()
    if auditor.has_errors:
        raise InputError(f"the drawing for {path} fails ezdxf's audit: {auditor.errors[0]}",
                         hint="this is a bug in mppf; report it with the design file")
    try:
        doc.saveas(path)
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror or exc}",
                         hint="check that the folder exists and is writable") from None
    return path


def _xy(points: np.ndarray) -> list[tuple[float, float]]:
    return [(float(x), float(y)) for x, y in points]


def _inside_corner(polygon: np.ndarray, corner: int, inset_mm: float) -> np.ndarray:
    """A point ``inset_mm`` inside a convex-ish polygon's corner, along the corner's bisector."""
    p = polygon[corner]
    before, after = polygon[corner - 1] - p, polygon[(corner + 1) % len(polygon)] - p
    bisector = before / np.linalg.norm(before) + after / np.linalg.norm(after)
    size = float(np.linalg.norm(bisector))
    if size < 1e-9:  # a straight run: inward normal of a counter-clockwise outline
        bisector, size = np.array([-after[1], after[0]]), float(np.linalg.norm(after))
    return p + inset_mm * bisector / size


def _boundary_loops(faces) -> list[np.ndarray]:
    """The boundary of a triangulation as closed loops of vertex indices (largest first not implied)."""
    edges = boundary_edges(faces)
    if edges.size == 0:
        raise GeometryError("the flat plate has no outline (its triangles close on themselves)")
    following: dict[int, list[int]] = {}
    for a, b in edges:
        following.setdefault(int(a), []).append(int(b))
        following.setdefault(int(b), []).append(int(a))
    loops, seen = [], set()
    for start in following:
        if start in seen:
            continue
        loop, previous, current = [start], None, start
        seen.add(start)
        while True:
            nxt = [v for v in following[current] if v != previous and (v not in seen or v == start)]
            if not nxt or nxt[0] == start:
                break
            previous, current = current, nxt[0]
            loop.append(current)
            seen.add(current)
        if len(loop) >= 3:
            loops.append(np.asarray(loop))
    return loops
