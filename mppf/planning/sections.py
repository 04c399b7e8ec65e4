"""Sections of a plate larger than the bed: the split, the pressing order, the marks, the blend.

Pure geometry of sectional forming; :mod:`mppf.planning.sectional` plans the strokes of every
section with it, :mod:`mppf.model.job_sections` stores them. Plate coordinates: the flat laid
on an unlimited bed (:func:`mppf.planning.placement.lay_flat`: long side along press x, centred on
the origin). A section is the plate shifted so that the bed's centre lies over the plate point
``bed_centre_mm``; the plate centre then lies at press x, y ``-bed_centre_mm``. The shifts between
sections are whole multiples of the punch pitch, so the punch axes of two sections fall on the
same plate points in their overlap. See ``docs/sections.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mppf.core.errors import LimitError
from mppf.core.validate import check_number
from mppf.model.press import PressConfig

TRANSITION_PITCHES = 3
"""Default width of a transition zone: this many punch pitches (4 punch rows shared by two sections)."""
MAX_SECTIONS_PER_AXIS = 20
"""Most sections along one axis of a plate (a 70 m plate on the example press)."""


@dataclass(frozen=True)
class SectionSplit:
    """How a plate is split into sections, in pressing order.

    Attributes
    ----------
    cells : list of (int, int)
        (along, across) index of each section, in the order they are pressed.
    bed_centres_mm : (n, 2) float
        Plate x, y under the bed's centre in each section (same order).
    counts : (int, int)
        Sections along x and across (y).
    spacing_mm : (2,) float
        Distance between neighbouring sections' bed centres along x and y (multiples of the pitch).
    transition_mm : (2,) float
        Width of the shared strip of neighbouring sections along x and y (0 where there is one section).
    """

    cells: list
    bed_centres_mm: np.ndarray
    counts: tuple[int, int]
    spacing_mm: np.ndarray
    transition_mm: np.ndarray

    @property
    def n_sections(self) -> int:
        return len(self.cells)


def split_plate(size_mm, press: PressConfig, *, transition_mm: float | None = None) -> SectionSplit:
    """Split a plate of ``size_mm`` (net, on the plate's own axes) into sections that each cover the bed.

    Along each axis the fewest sections whose neighbours share at least ``transition_mm``; the
    sections are spaced evenly by whole pitches and the whole set is centred on the plate.

    Order: along the long axis from the end at -x to the end at +x; across (when the plate is also
    wider than the bed) back and forth (serpentine) at each position along. So every new section
    meets formed plate on its trailing side only, the plate moves one way by equal shifts, and the
    unformed rest stays flat on the in-feed side.

    Parameters
    ----------
    size_mm : (2,) float
        Net plate extent along press x and y (mm).
    press : PressConfig
    transition_mm : float, optional
        Least width of the strip two neighbouring sections share; default ``TRANSITION_PITCHES`` pitches.

    Raises
    ------
    LimitError
        The bed is too short for the transition, or the plate would need too many sections.
    """
    size = np.asarray(size_mm, dtype=float).reshape(2)
    bed = np.array(press.bed_size_mm, dtype=float)
    pitch = np.array([press.pitch_x_mm, press.pitch_y_mm])
    zone = TRANSITION_PITCHES * float(pitch.max()) if transition_mm is None else check_number(
        "the transition width", transition_mm, low=0.0, unit="mm", hint="give e.g. --transition 450")
    along = [_positions(size[a], bed[a], pitch[a], zone, "xy"[a]) for a in (0, 1)]
    cells, centres = [], []
    for i, x in enumerate(along[0][0]):
        js = range(len(along[1][0])) if i % 2 == 0 else reversed(range(len(along[1][0])))
        for j in js:
            cells.append((i, j))
            centres.append((x, along[1][0][j]))
    counts = (len(along[0][0]), len(along[1][0]))
    spacing = np.array([along[0][1], along[1][1]])
    shared = np.where(np.array(counts) > 1, bed - spacing, 0.0)
    return SectionSplit(cells, np.array(centres, dtype=float), counts, spacing, shared)


def _positions(length: float, bed: float, pitch: float, zone: float, axis: str) -> tuple[np.ndarray, float]:
    """Bed-centre positions along one axis (centred on 0) and their spacing (a multiple of the pitch)."""
    if length <= bed + 1e-6:
        return np.zeros(1), 0.0
    if bed - pitch < zone - 1e-6:
        raise LimitError(f"the bed ({bed:.0f} mm along {axis}) is too short for sections sharing {zone:.0f} mm",
                         hint="give a narrower transition zone")
    for n in range(2, MAX_SECTIONS_PER_AXIS + 1):
        spacing = pitch * math.ceil((length - bed) / (n - 1) / pitch - 1e-9)
        if bed - spacing >= zone - 1e-6:
            return (np.arange(n) - (n - 1) / 2.0) * spacing, float(spacing)
    raise LimitError(f"the plate ({length:.0f} mm along {axis}) would need more than {MAX_SECTIONS_PER_AXIS} "
                     f"sections on a bed of {bed:.0f} mm", hint="check the plate's units (--units m?)")


def section_punches_plate(press: PressConfig, bed_centre_mm) -> tuple[np.ndarray, np.ndarray]:
    """Plate x, y of every punch axis in a section: (rows, cols) arrays each."""
    gx, gy = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    return gx + bed_centre_mm[0], gy + bed_centre_mm[1]


def index_offset(press: PressConfig, from_centre_mm, to_centre_mm) -> tuple[int, int]:
    """(rows, cols) to add to a punch index of one section to find the punch on the same plate point in another."""
    d = np.asarray(from_centre_mm, dtype=float) - np.asarray(to_centre_mm, dtype=float)
    return int(round(d[1] / press.pitch_y_mm)), int(round(d[0] / press.pitch_x_mm))


def shifted(grid, offset: tuple[int, int], fill=np.nan) -> np.ndarray:
    """``out[r, c] = grid[r + dr, c + dc]`` where that exists, ``fill`` elsewhere."""
    grid = np.asarray(grid)
    out = np.full(grid.shape, fill, dtype=np.result_type(grid.dtype, np.asarray(fill).dtype))
    dr, dc = offset
    rows, cols = grid.shape
    r0, r1 = max(0, -dr), min(rows, rows - dr)
    c0, c1 = max(0, -dc), min(cols, cols - dc)
    if r0 < r1 and c0 < c1:
        out[r0:r1, c0:c1] = grid[r0 + dr:r1 + dr, c0 + dc:c1 + dc]
    return out


def earlier_weight(press: PressConfig, bed_centre_mm, earlier_centre_mm, zone_mm: float, plate_half_mm) -> np.ndarray:
    """(rows, cols) weight of an earlier section's shape at each punch of this section.

    1 deep inside the earlier section's bed, falling smoothly (``3 s^2 - 2 s^3``) to 0 at its
    border over ``zone_mm``; 0 outside it. Only the borders inside the plate count (the earlier
    bed's edge at the plate's own edge is no border between sections). Its complement is the
    weight of this section's own shape, so the strokes blend from the formed plate into the new
    section without a step or a kink.

    Parameters
    ----------
    plate_half_mm : (2,) float
        Half the plate's extent along x and y (plate coordinates are centred on it).
    """
    px, py = section_punches_plate(press, bed_centre_mm)
    half = np.array(press.bed_size_mm) / 2.0
    plate_half = np.asarray(plate_half_mm, dtype=float)
    inside = np.full(px.shape, np.inf)
    for axis, p in ((0, px), (1, py)):
        for side in (-1.0, 1.0):
            border = earlier_centre_mm[axis] + side * half[axis]
            depth = side * (border - p)  # how far inside this border the punch lies (negative: beyond it)
            # a border between sections (not the plate's edge) that this section's bed reaches past
            crossed = side * (bed_centre_mm[axis] + side * half[axis] - border) > 1e-6
            if abs(border) < plate_half[axis] - 1e-6 and crossed:
                inside = np.minimum(inside, depth)
            else:
                inside = np.where(depth < -1e-6, -1.0, inside)
    s = np.clip(inside / max(zone_mm, 1e-9), 0.0, 1.0)
    return np.where(inside >= -1e-6, s * s * (3.0 - 2.0 * s), 0.0)


def mark_punches(active) -> np.ndarray:
    """(2, 2) int: (row, col) of the two punches a section's reference marks lie over.

    The row nearest the middle of the active punches with at least two active punches, and in it
    the first and the last active column: the longest base along the plate for placing it.

    Raises
    ------
    LimitError
        No row has two active punches.
    """
    active = np.asarray(active, dtype=bool)
    rows = [r for r in range(active.shape[0]) if active[r].sum() >= 2]
    if not rows:
        raise LimitError("the section covers no two punches of one row", hint="check the plate size and the press")
    mid = np.mean(np.nonzero(active)[0])
    r = min(rows, key=lambda k: (abs(k - mid), k))
    cols = np.nonzero(active[r])[0]
    return np.array([[r, cols[0]], [r, cols[-1]]], dtype=int)


def press_sequence(job) -> list:
    """What ``mppf press`` presses, in order: ``[(section or None, steps)]``.

    A single-piece job gives one entry ``(None, job.steps)``; a sectional job one per section, to be
    pressed after the operator has placed the plate by that section's marks.
    """
    if job.sections is None:
        return [(None, job.steps)]
    return [(s, s.steps) for s in job.sections]


def section_job(job, index: int):
    """One section of a sectional job as a single-piece :class:`~mppf.model.job.Job`.

    Its steps, transforms and plate layout are the section's; its reports the section's with the
    job's inputs, and ``piece`` says which section it is (``index``, ``of``, ``plate_centre_mm``,
    ``own_weight``), so the single-piece stages (the press driver, the comparison at the punches,
    the correction) can work on one section at a time.

    Raises
    ------
    InputError
        The job has no sections, or no section ``index`` (1-based).
    """
    import dataclasses

    from mppf.core.errors import InputError
    from mppf.model.job import Job
    from mppf.model.job_provenance import SectionPiece

    if job.sections is None:
        raise InputError("the job is a single piece (no sections)")
    if not 1 <= index <= len(job.sections):
        raise InputError(f"section {index} does not exist: the job has sections 1..{len(job.sections)}")
    s = job.sections[index - 1]
    piece = SectionPiece(index=s.index, of=len(job.sections), plate_centre_mm=np.asarray(s.plate_centre_mm, float),
                         own_weight=s.own_weight)
    return Job(press=job.press, thickness_mm=job.thickness_mm, steps=list(s.steps), tf_press_design=s.tf_press_design,
               tf_press_flat=s.tf_press_flat, layout=s.layout,
               reports=dataclasses.replace(s.reports, inputs=job.reports.inputs), piece=piece)


def placement_text(section, previous=None, label=None) -> str:
    """The operator's instruction for placing the plate for a section (one line).

    The marks come over their punches as the section is formed; lying flat the plate has them
    further apart (the draw-in of the bend), and the line says by how much when it is 0.5 mm or more.
    """
    from mppf.core.transform import apply_tf

    (r1, c1), (r2, c2) = np.asarray(section.mark_punches, dtype=int)
    label = label or (lambda r, c: f"row {r + 1}, col {c + 1}")
    text = (f"section {section.index}: place the plate with mark {section.index}a over punch {label(r1, c1)} "
            f"and mark {section.index}b over punch {label(r2, c2)}")
    flat_xy = apply_tf(section.tf_press_flat, section.marks_flat_mm)[:, :2]
    off = flat_xy - np.asarray(section.marks_press_mm, dtype=float)
    if np.abs(off).max() >= 0.5:
        text += (f"; lying flat the marks are {off[0, 0]:+.0f} / {off[1, 0]:+.0f} mm along x from them and come "
                 "over them as the section is formed")
    if previous is not None:
        dx, dy = section.shift_from_mm(previous)
        text += f" (the plate moves {dx:+.0f} mm along x, {dy:+.0f} mm along y from section {previous.index})"
    return text
