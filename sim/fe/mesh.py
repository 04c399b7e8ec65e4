"""The FE plate's mesh: hexahedral layers over the outline, node columns on the punch axes.

The plate is meshed in press x, y (of its first placement) with a structured grid whose lines
pass through the punch axes: ``cells_per_pitch`` cells between neighbouring axes, the lines
clipped to the outline's bounding box (a line closer than a quarter cell to the box edge is
dropped). A cell is kept when its centre lies inside the outline (non-rectangular outlines
get a stepped edge within half a cell). Through the thickness the plate has ``layers``
C3D8I elements (incompatible modes: bending without shear locking), the nodes of a column
at ``k / layers`` of the LOCAL thickness (the thickness scatter of the physical plate), the
bottom skin on z = 0.

Each punch pair over the plate acts on the column of nodes at its axis: the lower tip on the
bottom node, the upper tip on the top node (:mod:`mppf.sim.fe.deck`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mppf.core.errors import GeometryError
from mppf.core.polygon import contains


def _lines(axes_mm: np.ndarray, pitch_mm: float, cells: int, lo: float, hi: float) -> np.ndarray:
    """Grid lines (n,) through the punch axes, ``cells`` per pitch, clipped to [lo, hi], mm.

    The axes inside the box are always lines; a subdividing line closer than a quarter cell to
    the box's edge is dropped (no sliver elements).
    """
    step = pitch_mm / cells
    start = axes_mm.min() - step * np.ceil((axes_mm.min() - lo) / step)
    lines = start + step * np.arange(int(np.ceil((hi - start) / step)) + 1)
    on_axis = np.abs((lines - axes_mm.min()) / pitch_mm - np.round((lines - axes_mm.min()) / pitch_mm)) < 1e-9
    margin = np.where(on_axis, 1e-6, 0.25 * step)
    inner = lines[(lines > lo + margin) & (lines < hi - margin)]
    return np.concatenate([[lo], inner, [hi]])


@dataclass(frozen=True, eq=False)
class PlateMesh:
    """Nodes, hexahedra and punch columns of one plate.

    Attributes
    ----------
    xyz_mm : (n, 3) float
        Node coordinates (node id = index + 1), press x, y of the first placement, z up.
    hexes : (e, 8) int
        Node ids of the C3D8I elements (element id = index + 1).
    hex_centre_xy_mm : (e, 2) float
        Element centres in x, y.
    column : (ny, nx, layers + 1) int
        Node id of each grid point and level (0 where the point is not in the mesh).
    x_mm, y_mm : (nx,), (ny,) float
        Grid lines.
    punch_index : (m, 2) int
        Row, column of the press of each punch pair over the plate.
    punch_xy_mm : (m, 2) float
        Their axes.
    bottom, top, middle : (m,) int
        Node ids of the bottom, top and mid-thickness node at each punch axis.
    thickness_mm : (m,) float
        Local thickness at each punch axis.
    layers : int
    """

    xyz_mm: np.ndarray
    hexes: np.ndarray
    hex_centre_xy_mm: np.ndarray
    column: np.ndarray
    x_mm: np.ndarray
    y_mm: np.ndarray
    punch_index: np.ndarray
    punch_xy_mm: np.ndarray
    bottom: np.ndarray
    top: np.ndarray
    middle: np.ndarray
    thickness_mm: np.ndarray
    layers: int

    @property
    def node_count(self) -> int:
        """Number of nodes."""
        return len(self.xyz_mm)


def build_mesh(press, outline_xy_mm, thickness_at, cells_per_pitch: int, layers: int) -> PlateMesh:
    """The mesh of a plate on a press.

    Parameters
    ----------
    press : PressConfig
        Punch axes and pitches.
    outline_xy_mm : (k, 2) float
        The plate's outline in press x, y, mm.
    thickness_at : callable
        Local thickness (n,) of press x, y (n, 2), mm.
    cells_per_pitch : int
        Element edges between neighbouring punch axes.
    layers : int
        Elements through the thickness.

    Returns
    -------
    PlateMesh

    Raises
    ------
    GeometryError
        Fewer than 3 punch pairs over the plate.
    """
    outline = np.asarray(outline_xy_mm, dtype=float)
    lo, hi = outline.min(axis=0), outline.max(axis=0)
    x = _lines(press.punch_x_mm, press.pitch_x_mm, cells_per_pitch, lo[0], hi[0])
    y = _lines(press.punch_y_mm, press.pitch_y_mm, cells_per_pitch, lo[1], hi[1])
    cx, cy = np.meshgrid(0.5 * (x[1:] + x[:-1]), 0.5 * (y[1:] + y[:-1]))
    kept = contains(outline, np.column_stack([cx.ravel(), cy.ravel()]), tolerance_mm=1e-6).reshape(cx.shape)
    used = np.zeros((len(y), len(x)), dtype=bool)
    for dj, di in ((0, 0), (0, 1), (1, 0), (1, 1)):
        used[dj:dj + kept.shape[0], di:di + kept.shape[1]] |= kept
    jj, ii = np.nonzero(used)
    xy = np.column_stack([x[ii], y[jj]])
    t = np.asarray(thickness_at(xy), dtype=float)
    levels = np.arange(layers + 1) / layers
    n_col = len(xy)
    column = np.zeros((len(y), len(x), layers + 1), dtype=int)
    for k in range(layers + 1):
        column[jj, ii, k] = k * n_col + np.arange(n_col) + 1
    xyz = np.concatenate([np.column_stack([xy, t * level]) for level in levels])
    hexes = []
    ej, ei = np.nonzero(kept)
    for k in range(layers):
        base = [column[ej, ei, k], column[ej, ei + 1, k], column[ej + 1, ei + 1, k], column[ej + 1, ei, k]]
        top = [column[ej, ei, k + 1], column[ej, ei + 1, k + 1], column[ej + 1, ei + 1, k + 1],
               column[ej + 1, ei, k + 1]]
        hexes.append(np.column_stack(base + top))
    hexes = np.concatenate(hexes)
    centres = np.tile(np.column_stack([cx[kept], cy[kept]]), (layers, 1))
    index, axes, (gj, gi) = _punch_columns(press, x, y, column)
    return PlateMesh(xyz_mm=xyz, hexes=hexes, hex_centre_xy_mm=centres, column=column, x_mm=x, y_mm=y,
                     punch_index=index, punch_xy_mm=axes, bottom=column[gj, gi, 0],
                     top=column[gj, gi, layers], middle=column[gj, gi, layers // 2],
                     thickness_mm=np.asarray(thickness_at(axes), dtype=float), layers=layers)


def _punch_columns(press, x: np.ndarray, y: np.ndarray, column: np.ndarray):
    """The punch pairs whose axis is a node column of the mesh.

    Returns
    -------
    index : (m, 2) int
        Row, column of each pair on the press.
    axes : (m, 2) float
        Their axes, mm.
    grid : tuple of (m,) int
        Their grid row and column in the mesh.

    Raises
    ------
    GeometryError
        Fewer than 3 such pairs.
    """
    rows, cols = np.meshgrid(np.arange(press.rows), np.arange(press.cols), indexing="ij")
    index = np.column_stack([rows.ravel(), cols.ravel()])
    axes = np.column_stack([press.punch_x_mm[index[:, 1]], press.punch_y_mm[index[:, 0]]])
    gi = np.searchsorted(x, axes[:, 0]).clip(0, len(x) - 1)
    gj = np.searchsorted(y, axes[:, 1]).clip(0, len(y) - 1)
    on = (np.abs(x[gi] - axes[:, 0]) < 1e-6) & (np.abs(y[gj] - axes[:, 1]) < 1e-6)
    on &= column[gj, gi, 0] > 0
    if on.sum() < 3:
        raise GeometryError(f"the plate covers {int(on.sum())} punch pair(s) of the press, at least 3 are needed",
                            hint="give the plate's outline in press x, y (mm)")
    return index[on], axes[on], (gj[on], gi[on])
