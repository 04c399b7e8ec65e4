"""Hull stations and girth: where a plate given by frames and seams lies on a CAD hull.

Shell plates are laid out on the shell expansion: along the ship by x (frames, butts),
around the station by the girth, the length measured along the hull station from the
keel (the centreline, y = 0) up and round the bilge (seams). Hull coordinates: x forward,
y to port, z up; the model is a half hull on the port side (y >= 0).

A station x = const is traced from its keel point by predictor-corrector steps on the
exact surface (:func:`mppf.geometry.cad_query.intersect_near`): a step along the station's
tangent, then back onto the surface along the station's normal in the plane x = const.
It ends where the surface ends (the deck edge, a knuckle, the centreline at the deck).
The girth adds up the steps as circular arcs (chord c, tangents turning through theta:
``c (theta / 2) / sin(theta / 2)``).
"""

from __future__ import annotations

import numpy as np

from mppf.core.errors import GeometryError
from mppf.geometry.cad import CadModel
from mppf.geometry.cad_query import intersect_lines, intersect_near

STEP_FRACTION = 1.0 / 100.0
"""Longest step along a station, as a fraction of the model's diagonal (2.4 m on a 243 m hull)."""

TURN_RAD = 0.08
"""Steps are sized so that the station's tangent turns about this much in one (a step turning
more than twice this is taken again, shorter): each chord is counted as the circular arc that
turns through the angle between the tangents at its ends, which makes the girth exact to about
1e-6 of it."""

END_HALVINGS = 8
"""Where a step leaves the surface, it is halved up to this many times: a station's end is found
to within a 256th of a step (1 mm)."""

MAX_STEPS = 20_000
GIRTH_ITERATIONS = 3

KEEL_OFFSET_FRACTION = 1e-6
"""The keel point is taken this fraction of the model size off the centreline (on the face, not its edge)."""


def trace_stations(model: CadModel, x_mm, girth_max_mm: float, step_mm: float | None = None):
    """Trace the stations at ``x_mm`` from the keel to ``girth_max_mm`` (or their end).

    ``step_mm`` is the longest step (default :data:`STEP_FRACTION` of the model's diagonal);
    each step is shortened where the station turns (:data:`TURN_RAD`).

    Returns
    -------
    points : (s, k, 3) float, mm
        Exact points along each station, ``step_mm`` apart (shorter steps near its end;
        after it, or once ``girth_max_mm`` is reached, the last point repeated).
    girth : (s, k) float, mm
        Girth of each point from the keel (non-decreasing along each row).
    normal : (s, k, 3) float
        Unit normal of each station in its plane x = const.
    """
    x = np.asarray(x_mm, dtype=float).ravel()
    diagonal = float(np.linalg.norm(np.ptp(model.bounds_mm, axis=0)))
    offset = KEEL_OFFSET_FRACTION * diagonal
    longest = STEP_FRACTION * diagonal if step_mm is None else float(step_mm)
    # 1. keel points: the surface seen from below, just off the centreline
    keel = _keel(model, x, offset)
    # 2. march along each station: a step along its tangent, back onto the surface along its normal
    face, uv = keel.face.copy(), keel.uv.copy()
    start = np.tile([0.0, 1.0, 0.0], (x.size, 1))  # away from the centreline
    tangent, in_plane = _station_frame(model, face, uv, np.ones(x.size, dtype=bool), start)
    points, girth, normal = [keel.points_mm], [np.full(x.size, offset)], [in_plane]
    alive, step = np.ones(x.size, dtype=bool), np.full(x.size, longest)
    for _ in range(MAX_STEPS):
        rows = np.flatnonzero(alive & (girth[-1] < girth_max_mm))
        if rows.size == 0:
            break
        hit = intersect_near(model, points[-1][rows] + step[rows, None] * tangent[rows], in_plane[rows])
        good = hit.found & (hit.distance_mm < step[rows])
        # off the surface: halve the step; the station ends where it is below longest / 2^END_HALVINGS
        _halve(step, alive, rows[~good], longest)
        # on it, but turning more than twice TURN_RAD: a shorter step instead (the arc would be wrong)
        face_try, uv_try, reached = _tried(face, uv, hit, rows, good)
        new_tangent, turned = _station_frame(model, face_try, uv_try, reached, tangent)
        angle = _turn(tangent, new_tangent)
        sharp = reached & (angle > 2.0 * TURN_RAD) & (step > longest / 2**END_HALVINGS)
        step[sharp] *= np.maximum(TURN_RAD / angle[sharp], 0.25)
        stepped = reached & ~sharp
        # the step taken: the new point, its girth as a circular arc, its tangent and normal
        new = points[-1].copy()  # rows that did not step stay where they were
        new[stepped] = hit.points_mm[good][stepped[rows[good]]]
        face[stepped], uv[stepped] = face_try[stepped], uv_try[stepped]
        chord = np.linalg.norm(new - points[-1], axis=1)
        girth.append(np.where(stepped, girth[-1] + chord * _arc_factor(angle), girth[-1]))
        tangent = np.where(stepped[:, None], new_tangent, tangent)
        in_plane = np.where(stepped[:, None], turned, in_plane)
        points.append(new)
        normal.append(in_plane)
        # the next step: the tangent should turn about TURN_RAD in it
        grow = np.clip(TURN_RAD / np.maximum(angle, 1e-9), 0.5, 2.0)
        step[stepped] = np.minimum(step[stepped] * grow[stepped], longest)
    else:
        raise GeometryError(f"a hull station did not end in {MAX_STEPS} steps", hint="check the hull model")
    return np.stack(points, axis=1), np.stack(girth, axis=1), np.stack(normal, axis=1)


def _keel(model: CadModel, x: np.ndarray, offset_mm: float):
    """The keel point of each station x (s,) mm: the surface seen from below, ``offset_mm`` off the centreline.

    Returns the :func:`~mppf.geometry.cad_query.intersect_lines` hits; :class:`GeometryError`
    where a station has none.
    """
    below = np.column_stack([x, np.full_like(x, offset_mm), np.full_like(x, model.bounds_mm[0, 2] - 1.0)])
    keel = intersect_lines(model, below, [0.0, 0.0, 1.0], seen_from=[0.0, 0.0, -1.0])
    if not keel.found.all():
        first = x[~keel.found][0]
        raise GeometryError(f"the hull has no keel at x = {first:.0f} mm: no surface below the centreline there",
                            hint="give stations between the stern and the stem, in full-scale hull coordinates")
    return keel


def _halve(step: np.ndarray, alive: np.ndarray, failed: np.ndarray, longest_mm: float) -> None:
    """Halve the step (s,) mm of the ``failed`` rows; end the stations whose step is below the last halving."""
    step[failed] /= 2.0
    alive[failed[step[failed] < longest_mm / 2**END_HALVINGS]] = False


def _tried(face: np.ndarray, uv: np.ndarray, hit, rows: np.ndarray, good: np.ndarray):
    """Faces (s,) and (u, v) (s, 2) with the ``good`` hits of ``rows`` in place, and which rows (s,) bool reached one."""
    face_try, uv_try = face.copy(), uv.copy()
    face_try[rows[good]], uv_try[rows[good]] = hit.face[good], hit.uv[good]
    reached = np.zeros(face.shape[0], dtype=bool)
    reached[rows[good]] = True
    return face_try, uv_try, reached


def _turn(t0: np.ndarray, t1: np.ndarray) -> np.ndarray:
    """Angle (rad) between unit tangents, row by row."""
    return np.arccos(np.clip(np.einsum("nd,nd->n", t0, t1), -1.0, 1.0))


def _arc_factor(angle: np.ndarray) -> np.ndarray:
    """Arc length over chord of a circular arc whose tangents turn through ``angle``."""
    half = 0.5 * angle
    return np.where(half > 1e-8, half / np.maximum(np.sin(half), 1e-300), 1.0)


def _station_frame(model: CadModel, face: np.ndarray, uv: np.ndarray, alive: np.ndarray, previous: np.ndarray):
    """Unit tangent along each station (continuing ``previous``) and its normal in the plane x = const.

    ``face`` and ``uv`` say where each station's last point lies on the model; rows that are
    not ``alive`` (or on no face) keep ``previous`` and get a zero normal.
    """
    tangent, normal = previous.copy(), np.zeros_like(previous)
    x_axis = np.array([1.0, 0.0, 0.0])
    for index in np.unique(face[alive & (face >= 0)]):
        rows = np.flatnonzero(alive & (face == index))
        s_u, s_v, *_ = model.derivatives(model.faces[index], uv[rows])
        t = np.cross(x_axis, np.cross(s_u, s_v))
        t /= np.maximum(np.linalg.norm(t, axis=1), 1e-300)[:, None]
        t *= np.where(np.einsum("nd,nd->n", t, previous[rows]) < 0, -1.0, 1.0)[:, None]
        tangent[rows] = t
        normal[rows] = np.cross(x_axis, t)
    return tangent, normal


def sample_girth(model: CadModel, x_mm, girth_mm) -> np.ndarray:
    """Points of the hull at stations ``x_mm`` (s,) and girths ``girth_mm`` (g,) from the keel.

    Each point is stepped to from the traced station point before it, along the station, the
    step corrected until the girth it reaches is the one asked for (secant iterations).

    Returns
    -------
    (s, g, 3) float, mm
        Row k is the station at ``x_mm[k]``; each point lies on the exact surface.

    Raises
    ------
    GeometryError
        A station without a keel, or one that ends before the largest girth.
    """
    x = np.asarray(x_mm, dtype=float).ravel()
    g = np.asarray(girth_mm, dtype=float).ravel()
    # 1. the stations, traced past the largest girth
    points, girth, normal = trace_stations(model, x, float(g.max()))
    # 2. for each sample, the traced point before it
    base = []
    for k in range(x.size):
        ok = np.r_[True, np.diff(girth[k]) > 0]  # each point once (repeated where a row waited)
        if girth[k][ok][-1] < g.max() - 1e-6:
            raise GeometryError(
                f"the station at x = {x[k]:.0f} mm ends at a girth of {girth[k][ok][-1]:.0f} mm, "
                f"before the plate's {g.max():.0f} mm (the deck edge or a knuckle)",
                hint="give girths within the station (from the keel, mm at full scale)")
        i = np.clip(np.searchsorted(girth[k][ok], g, side="right") - 1, 0, int(ok.sum()) - 1)
        base.append((points[k][ok][i], normal[k][ok][i], girth[k][ok][i]))
    p0, n0, g0 = (np.concatenate([b[j] for b in base]) for j in range(3))
    target = np.tile(g, x.size)
    t0 = np.cross(n0, [1.0, 0.0, 0.0])  # the station's tangent there (n0 = x-axis cross tangent)
    # 3. step along the station from there until the girth reached is the one asked for
    step = np.maximum(target - g0, 0.0)  # girths below the keel point's (a fraction of a micron) are the keel
    for _ in range(GIRTH_ITERATIONS):
        hit = intersect_near(model, p0 + step[:, None] * t0, n0)
        if not hit.found.all():
            first = int(np.argmin(hit.found))
            raise GeometryError(f"the station at x = {x[first // g.size]:.0f} mm could not be sampled at girth "
                                f"{target[first]:.0f} mm", hint="give girths within the station")
        tangent, _ = _station_frame(model, hit.face, hit.uv, np.ones(target.size, dtype=bool), t0)
        reached = g0 + np.linalg.norm(hit.points_mm - p0, axis=1) * _arc_factor(_turn(t0, tangent))
        step = np.maximum(step + target - reached, 0.0)
    return hit.points_mm.reshape(x.size, g.size, 3)
