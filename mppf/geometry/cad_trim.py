"""Trimming loops of a CAD face in its parameter space, and a raster of where the face is.

A trimmed face is the part of its surface's parameter domain inside its loops (outer loop
and holes: inside an odd number of them). The loops are its boundary curves mapped into
the parameters (gmsh ``reparametrizeOnSurface``) and sampled until the chords stray less
than a tolerance from them (:func:`sample_on_face`); straight runs are thinned
(:func:`simplify`) and the curves joined end to start (:func:`chain`).

Testing every query against the loops is slow for loops of hundreds of corners, so a
:class:`TrimRaster` classifies once the cells of a grid over the domain: a cell crossed by a
loop (or near one) is "undecided", every other cell is inside or outside as its centre is
(:func:`mppf.core.polygon.contains`). Queries in decided cells are answered from the grid.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.polygon import contains

LOOP_SAMPLES, LOOP_SAMPLES_MAX = 64, 4096
"""Points per trimming curve sampled for a face's parameter-space loop (more where it bends) ..."""

LOOP_SIMPLIFY = 1e-5
"""... until the chords stray less than this fraction of the parameter domain from the curve;
then the points within that of a straight run are dropped."""

RASTER_CELLS = 128
"""Cells of a face's :class:`TrimRaster` along u and along v."""

UNDECIDED, OUTSIDE, INSIDE = -1, 0, 1


@dataclass(frozen=True, eq=False)
class TrimRaster:
    """Where a trimmed face is, cell by cell of a grid over its parameter domain.

    Attributes
    ----------
    low, high : (2,) float
        The parameter domain.
    state : (cells, cells) int8
        :data:`INSIDE`, :data:`OUTSIDE` or :data:`UNDECIDED` (a loop passes near the cell).
    """

    low: np.ndarray
    high: np.ndarray
    state: np.ndarray

    def lookup(self, uv: np.ndarray) -> np.ndarray:
        """State of the cell of each parameter pair (n, 2); UNDECIDED off the domain (and on its edge)."""
        n = self.state.shape[0]
        cell = np.floor((uv - self.low) / np.maximum(self.high - self.low, 1e-300) * n).astype(np.int64)
        within = np.all((cell >= 0) & (cell < n), axis=1)
        state = np.full(uv.shape[0], UNDECIDED, dtype=np.int8)
        state[within] = self.state[cell[within, 0], cell[within, 1]]
        return state


def trim_raster(loops, low: np.ndarray, high: np.ndarray, band: float, cells: int = RASTER_CELLS) -> TrimRaster:
    """Classify the cells of a ``cells`` x ``cells`` grid over [low, high] against the loops.

    Cells within ``band`` (parameters) plus one cell of a loop are undecided.
    """
    span = np.maximum(high - low, 1e-300)
    size = span / cells
    undecided = np.zeros((cells, cells), dtype=bool)
    for loop in loops:
        # every cell a loop segment passes through, sampled at half a cell
        a = (loop - low) / size
        b = (np.roll(loop, -1, axis=0) - low) / size
        count = np.ceil(2.0 * np.linalg.norm(b - a, axis=1)).astype(np.int64) + 1
        t = np.concatenate([np.linspace(0.0, 1.0, k) for k in count])
        start = np.repeat(a, count, axis=0)
        along = start + t[:, None] * (np.repeat(b, count, axis=0) - start)
        cell = np.clip(np.floor(along).astype(np.int64), 0, cells - 1)
        undecided[cell[:, 0], cell[:, 1]] = True
    for _ in range(1 + int(np.ceil(band / float(size.min())))):  # widen by the band, and a cell
        grown = undecided.copy()
        grown[1:] |= undecided[:-1]
        grown[:-1] |= undecided[1:]
        grown[:, 1:] |= grown[:, :-1].copy()
        grown[:, :-1] |= grown[:, 1:].copy()
        undecided = grown
    centres = low + (np.stack(np.meshgrid(np.arange(cells), np.arange(cells), indexing="ij"), axis=-1) + 0.5) * size
    decided = ~undecided
    flags = np.zeros(int(decided.sum()), dtype=bool)
    for loop in loops:
        flags ^= contains(loop, centres[decided])
    state = np.full((cells, cells), UNDECIDED, dtype=np.int8)
    state[decided] = np.where(flags, INSIDE, OUTSIDE)
    return TrimRaster(np.asarray(low, dtype=float), np.asarray(high, dtype=float), state)


def sample_on_face(gmsh, curve: int, face_tag: int, target: float) -> tuple[np.ndarray, float]:
    """A trimming curve in the face's parameters, sampled until its chords stray less than ``target``.

    Returns the samples (k, 2) and the chords' largest sagitta (measured at the midpoints).
    """
    (t0,), (t1,) = gmsh.model.getParametrizationBounds(1, curve)
    n = LOOP_SAMPLES
    while True:
        t = np.linspace(t0, t1, 2 * n - 1)
        uv = np.asarray(gmsh.model.reparametrizeOnSurface(1, curve, t, face_tag), dtype=float).reshape(-1, 2)
        sagitta = float(np.linalg.norm(uv[1::2] - 0.5 * (uv[0:-1:2] + uv[2::2]), axis=1).max())
        if sagitta <= target or n >= LOOP_SAMPLES_MAX:
            return uv[::2], sagitta
        n = 4 * n


def simplify(polyline: np.ndarray, tolerance: float) -> np.ndarray:
    """Douglas-Peucker: the corners of ``polyline`` (k, 2) that keep it within ``tolerance``."""
    keep = np.zeros(polyline.shape[0], dtype=bool)
    keep[[0, -1]] = True
    todo = [(0, polyline.shape[0] - 1)]
    while todo:
        first, last = todo.pop()
        if last - first < 2:
            continue
        a, b = polyline[first], polyline[last]
        inner = polyline[first + 1:last]
        ab = b - a
        length = float(np.linalg.norm(ab))
        if length > 0:
            off = np.abs(ab[0] * (inner[:, 1] - a[1]) - ab[1] * (inner[:, 0] - a[0])) / length
        else:
            off = np.linalg.norm(inner - a, axis=1)
        worst = int(np.argmax(off))
        if off[worst] > tolerance:
            keep[first + 1 + worst] = True
            todo += [(first, first + 1 + worst), (first + 1 + worst, last)]
    return polyline[keep]


def chain(pieces: list[np.ndarray]) -> np.ndarray | None:
    """Join the sampled curves of one loop end to start (each turned as needed); None if they do not close."""
    if not pieces:
        return None
    loop = [pieces[0]]
    if len(pieces) > 1:
        first, second = pieces[0], pieces[1]
        ends = [np.linalg.norm(first[-1] - second[[0, -1]], axis=1).min(),
                np.linalg.norm(first[0] - second[[0, -1]], axis=1).min()]
        loop = [first if ends[0] <= ends[1] else first[::-1]]
    for piece in pieces[1:]:
        end = loop[-1][-1]
        loop.append(piece if np.linalg.norm(piece[0] - end) <= np.linalg.norm(piece[-1] - end) else piece[::-1])
    joined = np.vstack(loop)
    span = max(float(np.ptp(joined, axis=0).max()), 1e-300)
    if np.linalg.norm(joined[0] - joined[-1]) > 0.01 * span:
        return None  # an open chain (a seam of a periodic surface): not a loop in the plane
    return joined
