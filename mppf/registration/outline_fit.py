"""Re-placing a registered scan by its outline (in the plane) and its deviations (out of it).

Best-fit registration trades shape errors against rigid moves: a plate formed with a
few mm of error fits best turned and shifted, so that the deviations land beside the
punches that caused them. On the press the plate's outline fixes it in the plane and
the strokes act along press z; so, in the press's coordinates when ``tf_press_design``
is given (else in the design's frame, its normal as "z"), :func:`refit_outline`

1. fits the scan's edge, seen along z, to the outline of the design skin that was
   measured (:func:`fit_outline_2d`: a turn about z and a shift across it; a turn below
   ``OutlineFit.min_turn_deg`` is not applied, the fit is then redone as a shift only);
2. removes the robust best plane ``dz ~ a + b x + c y`` of the net plate's deviations
   along z by a shift along z and small tilts about the plate's centre;
3. repeats both (``OutlineFit.rounds``): a tilt moves a curved plate's edge a little.

Seen from above the press is the view of the planner (the plate's outline as cut) and
of the strokes, so the punch deviations come out where the punches are. The math is in
``docs/compare.md``; lengths in mm.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from mppf.core.grid import best_plane
from mppf.core.kdtree import KDTree
from mppf.core.polygon import area, closest_on_segments, convex_inset, convex_outline, inward_normals, offset_convex
from mppf.core.rigid import fit_rigid
from mppf.core.transform import apply_rotation, apply_tf, make_tf, rotvec_to_matrix
from mppf.registration.settings import OutlineFit

Heights = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]
"""``heights(tf)``: for the net plate's measured points moved by ``tf`` (measured -> design):
their positions (k, 3) in design coordinates, the unit design normals (k, 3) at their foot
points (design coordinates, pointing "up": the side of positive deviations) and their
normal deviations (k,), mm."""


@dataclass(frozen=True, eq=False)
class OutlineDesign:
    """The design side of an outline fit.

    Attributes
    ----------
    frame : LocalFrame
        The design's frame.
    design_uv : (m, 2) float, mm
        The design points in that frame.
    skin_world : (m, 3) float, mm
        The measured skin of the net design at those points, design coordinates.
    tf_press_design : (4, 4) float or None
        Design -> press; None: seen along the design's normal.
    margin_mm : float
        Trim margin the scan still carries: the outline is grown by it.
    """

    frame: object
    design_uv: np.ndarray
    skin_world: np.ndarray
    tf_press_design: np.ndarray | None
    margin_mm: float


def refit_outline(measured, tf, design: OutlineDesign, heights: Heights,
                  settings: OutlineFit = OutlineFit()) -> tuple[np.ndarray, str]:
    """The measured -> design transform re-placed by the outline, and a note (see the module docstring).

    Parameters
    ----------
    measured : (n, 3) float, mm
        The scan.
    tf : (4, 4) float
        Its registration, measured -> design.
    design : OutlineDesign
        The design's frame, points, measured skin, press pose and trim margin.
    heights : Heights
        The net plate's deviations at a transform.
    settings : OutlineFit

    Returns
    -------
    tf : (4, 4) float
        Falls back to the given ``tf`` when the scan shows too little edge or the fit
        wants an implausible move (the note says so).
    note : str
    """
    view, corners = _view(design)
    unview = np.linalg.inv(view)
    size_mm = float(np.ptp(design.design_uv, axis=0).max())
    turns, shifts = [], []
    for _ in range(settings.rounds):
        # in the plane: the scan's edge fitted to the outline
        total, skipped = _in_plane(apply_tf(view @ tf, measured)[:, :2], corners, size_mm, settings)
        if skipped:
            return tf, skipped
        turns.append(float(np.degrees(np.arctan2(total[1, 0], total[0, 0]))))
        shifts.append(float(np.hypot(*total[:2, 2])))
        in_plane = np.eye(4)
        in_plane[:2, :2] = total[:2, :2]
        in_plane[:2, 3] = total[:2, 2]
        tf = unview @ in_plane @ view @ tf
        # out of plane: remove the deviations' robust best plane (along z) by a shift and two tilts
        for _ in range(settings.lift_passes):
            points, normals, deviation = heights(tf)
            n_z = apply_rotation(view, normals)[:, 2]  # the deviation along the normal as a height along z
            at = apply_tf(view, points)[:, :2]
            a, b, c = best_plane(at[:, 0], at[:, 1], deviation / np.maximum(n_z, settings.slope_floor), robust=True)
            lift = make_tf(rotvec_to_matrix([-c, b, 0.0]), [0.0, 0.0, -a])
            tf = unview @ lift @ view @ tf
    seen = "from above the press" if design.tf_press_design is not None else "along the design's normal"
    return tf, (f"outline fit ({seen}): turned {sum(turns):+.2f} deg and shifted {shifts[0]:.1f} mm in the plane"
                + (f", then {', '.join(f'{s:.1f}' for s in shifts[1:])} mm" if len(shifts) > 1 else ""))


def _view(design: OutlineDesign) -> tuple[np.ndarray, np.ndarray]:
    """(4, 4) design -> view transform ("z" the viewing direction) and the outline's corners (k, 2) in it.

    Seen from above the press the view is centred on the skin (turns and tilts about the
    plate's centre); the outline is the skin's convex outline grown by the margin.
    """
    tf_press_design, margin_mm = design.tf_press_design, design.margin_mm
    if tf_press_design is None:
        return design.frame.tf_local_world, offset_convex(convex_outline(design.design_uv), margin_mm)
    press_design = np.asarray(tf_press_design, dtype=float)
    skin = apply_tf(press_design, design.skin_world)
    centre = np.eye(4)
    centre[:3, 3] = -skin.mean(axis=0)
    xy = skin[:, :2] + centre[:2, 3]
    return centre @ press_design, offset_convex(convex_outline(xy), margin_mm)


def _in_plane(xy, corners, size_mm: float, settings: OutlineFit) -> tuple[np.ndarray, str]:
    """(3, 3) turn and shift fitting the scan's edge (seen along z) to the outline, or a reason to skip."""
    spacing = float(np.median(KDTree(xy).query(xy, k=2)[0][:, 1]))
    # inside a convex outline a point's distance to it is the least of those to its edges' lines
    edge = convex_inset(convex_outline(xy), xy) < settings.edge_spacings * spacing
    if edge.sum() < settings.min_edge_points:
        return np.eye(3), "outline fit skipped: too few edge points in the scan"
    points = xy[edge]
    seg_a, seg_b = corners, np.roll(corners, -1, axis=0)
    total = fit_outline_2d(points, seg_a, seg_b, True, spacing, settings)
    if abs(float(np.degrees(np.arctan2(total[1, 0], total[0, 0])))) < settings.min_turn_deg:
        total = fit_outline_2d(points, seg_a, seg_b, False, spacing, settings)
    turn_deg = float(np.degrees(np.arctan2(total[1, 0], total[0, 0])))
    shift_mm = float(np.hypot(*total[:2, 2]))
    if abs(turn_deg) > settings.max_turn_deg or shift_mm > settings.max_shift_fraction * size_mm:
        return total, f"outline fit skipped: it wanted a turn of {turn_deg:.1f} deg and a shift of {shift_mm:.0f} mm"
    return total, ""


def fit_outline_2d(points, seg_a, seg_b, turn: bool, spacing_mm: float,
                   settings: OutlineFit = OutlineFit()) -> np.ndarray:
    """(3, 3) 2-D transform fitting a scan's edge to the outline segments (turn + shift, or shift only).

    A scan's edge is not its outermost points one by one: the scanner samples the plate
    at some spacing, so along an edge the outermost points stand up to a spacing in, and
    a hidden stretch (a clamp, a shadow) leaves only points further in. So each outline
    edge is cut into pieces about ``piece_spacings`` point spacings long, and the scan's
    edge along a piece is the low ``edge_quantile`` of its points' insets (distance
    inside the outline): the envelope of the points, not their mean. Pieces whose
    envelope lies far from the others' (a hidden stretch, the rim of an occlusion) are
    left out; the common inset of the rest (the sampling's) is removed; the pieces' edge
    points are then fitted to the outline by least squares, weighted by their length.

    Parameters
    ----------
    points : (n, 2) float, mm
        The scan's edge points.
    seg_a, seg_b : (k, 2) float, mm
        The outline's edges (a convex polygon's corners and the next ones).
    turn : bool
        Fit a turn and a shift (else a shift only).
    spacing_mm : float
        The scan's point spacing.
    settings : OutlineFit
    """
    inward, lengths, pieces_per_seg, first_piece = _cut(seg_a, seg_b, spacing_mm, settings)
    total = np.eye(3)
    rough, fine = True, 0
    for _ in range(settings.iterations):
        moved = points @ total[:2, :2].T + total[:2, 2]
        foot, index = closest_on_segments(moved, seg_a, seg_b)
        inset = np.einsum("nd,nd->n", moved - foot, inward[index])  # > 0 inside the outline
        along = np.linalg.norm(foot - seg_a[index], axis=1) / np.maximum(lengths[index], 1e-12)
        piece = first_piece[index] + np.minimum((along * pieces_per_seg[index]).astype(int), pieces_per_seg[index] - 1)
        dst, depth, seg, spread = _pieces(piece, index, foot, inset, along, settings.edge_quantile)
        if len(dst) < 4:
            break
        normal = inward[seg]
        weight = spread * lengths[seg] + spacing_mm
        src = dst + depth[:, None] * normal  # the scan's edge along each piece
        # the edge is the scan's envelope: once roughly placed (all pieces used), pieces standing
        # further in or out than most (their outer row of points missing, a hidden stretch, a
        # stray point) are left out, with a band that narrows from a few spacings to about
        # half a spacing around the outer quartile of the pieces' edges
        keep = _within_band(depth, None if rough else spacing_mm * max(settings.band_spacings[1],
                                                                      settings.band_spacings[0] * 0.7 ** fine))
        fine += 0 if rough else 1
        if keep.sum() < 4:
            break
        target = dst + float(np.median(depth[keep])) * normal  # remove the sampling's common inset
        step = _move(src[keep], target[keep], weight[keep], turn)
        total = step @ total
        small = np.hypot(*step[:2, 2]) < 1e-3 and abs(np.arctan2(step[1, 0], step[0, 0])) < 1e-7
        if rough and (small or np.hypot(*step[:2, 2]) < 0.05 * spacing_mm):
            rough = False  # roughly placed: from now on the envelope's outliers are left out
        elif small and fine > 6:
            break
    return total


def _cut(seg_a, seg_b, spacing_mm: float, settings: OutlineFit) -> tuple:
    """The outline's edges cut into pieces: inward normals (k, 2), lengths (k,) mm, pieces per edge (k,) and the
    index of each edge's first piece (k,)."""
    inward = inward_normals(seg_a, seg_b, counter_clockwise=area(seg_a) > 0)
    lengths = np.linalg.norm(seg_b - seg_a, axis=1)
    piece_mm = max(settings.piece_spacings * spacing_mm, 1e-6)
    pieces_per_seg = np.maximum(np.ceil(lengths / piece_mm).astype(int), 1)
    return inward, lengths, pieces_per_seg, np.concatenate([[0], np.cumsum(pieces_per_seg)[:-1]])


def _within_band(depth: np.ndarray, band_mm: float | None) -> np.ndarray:
    """(p,) bool: the pieces whose edge lies within ``band_mm`` of the outer quartile of all (None: every piece)."""
    if band_mm is None:
        return np.ones(len(depth), dtype=bool)
    return np.abs(depth - float(np.quantile(depth, 0.25))) <= band_mm


def _move(src: np.ndarray, target: np.ndarray, weight: np.ndarray, turn: bool) -> np.ndarray:
    """(3, 3) weighted least-squares turn and shift of ``src`` (p, 2) onto ``target`` (p, 2), or the shift only."""
    if turn:
        return fit_rigid(src, target, weight)
    step = np.eye(3)
    w = weight / weight.sum()
    step[:2, 2] = ((target - src) * w[:, None]).sum(axis=0)
    return step


def _pieces(piece, index, foot, inset, along, quantile: float):
    """Per piece of the outline with at least 3 edge points: foot mean, edge inset, segment, extent along it.

    Returns
    -------
    dst : (p, 2) float
        Mean foot point of the piece's points (on its straight segment).
    depth : (p,) float
        The ``quantile`` (linear interpolation) of their insets: the scan's edge there.
    segment : (p,) int
        The outline segment the piece belongs to.
    spread : (p,) float
        Extent of the points along the segment, as a fraction of its length.
    """
    order = np.lexsort((inset, piece))  # by piece, then inset
    p = piece[order]
    starts = np.flatnonzero(np.concatenate([[True], p[1:] != p[:-1]]))
    counts = np.diff(np.concatenate([starts, [p.size]]))
    ok = counts >= 3
    first, n = starts[ok], counts[ok]
    dst = np.add.reduceat(foot[order], starts, axis=0)[ok] / n[:, None]
    # the quantile as numpy computes it (method "linear"), group by group
    sorted_inset = inset[order]
    h = (n - 1) * quantile
    lo = np.floor(h).astype(int)
    t = h - lo
    a = sorted_inset[first + lo]
    b = sorted_inset[first + np.minimum(lo + 1, n - 1)]
    depth = np.where(t >= 0.5, b - (b - a) * (1 - t), a + (b - a) * t)
    spread = (np.maximum.reduceat(along[order], starts) - np.minimum.reduceat(along[order], starts))[ok]
    return dst, depth, index[order][first], spread
