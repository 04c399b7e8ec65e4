"""SVG pictures of punch matrices: colour scales, heat maps, legends, punch names.

Pure functions: numpy arrays in, SVG text out (escaped; no I/O, no web framework), so the
operator's panel, the placement output and the per-plate report draw the same pictures.
Matrices are drawn as the press is seen from above: columns left to right, row 1 at the
bottom (press y up), like :mod:`mppf.panel.placement`'s bed. Punches are named 1-based
("R3 C5" is the 3rd row, 5th column), the way the press is labelled
(:func:`mppf.model.job_parts.reference_corner_xy`: "row 1, column 1").
"""

from __future__ import annotations

import html
import math
import zlib

import numpy as np

VIRIDIS = ("#440154", "#472d7b", "#3b528b", "#2c728e", "#21918c", "#28ae80", "#5ec962", "#addc30", "#fde725")
"""Heights: matplotlib's viridis at 9 even stops (dark = low, yellow = high)."""

DIVERGING = ("#2166ac", "#4393c3", "#92c5de", "#d1e5f0", "#f7f7f7", "#fddbc7", "#f4a582", "#d6604d", "#b2182b")
"""Deviations: blue below (negative), white at 0, red above (ColorBrewer RdBu reversed)."""

NO_DATA = "#c8c8c8"
"""Cells without a value (NaN: inactive or not measured)."""

FLAG_COLOURS = {"lagging": "#ff8c00", "faulted": "#e00000", "off": "#ff8c00"}
"""Outline of a marked punch: lagging / off target (orange, dashed), faulted (red, with a cross)."""


def esc(text) -> str:
    """Text escaped for SVG / HTML."""
    return html.escape(str(text), quote=True)


def punch_name(row: int, col: int, base: int = 1) -> str:
    """The press's name of punch (``row``, ``col``) given 0-based: ``"R3 C5"`` (``base`` = first number)."""
    return f"R{int(row) + base} C{int(col) + base}"


def _hex_rgb(colour: str) -> tuple[int, int, int]:
    return int(colour[1:3], 16), int(colour[3:5], 16), int(colour[5:7], 16)


def colour(value: float, lo: float, hi: float, cmap=VIRIDIS) -> str:
    """The colour of ``value`` on the scale ``lo``..``hi`` (clipped; NaN: :data:`NO_DATA`)."""
    if value is None or not math.isfinite(value):
        return NO_DATA
    t = 0.5 if hi <= lo else min(1.0, max(0.0, (value - lo) / (hi - lo)))
    pos = t * (len(cmap) - 1)
    k = min(int(pos), len(cmap) - 2)
    f = pos - k
    a, b = _hex_rgb(cmap[k]), _hex_rgb(cmap[k + 1])
    return "#" + "".join(f"{round(x + f * (y - x)):02x}" for x, y in zip(a, b))


def ink(fill: str) -> str:
    """Black or white text on ``fill``, whichever reads better."""
    r, g, b = _hex_rgb(fill)
    return "#000" if 0.299 * r + 0.587 * g + 0.114 * b > 140 else "#fff"


def value_text(value: float) -> str:
    """A punch value short enough for its cell: one decimal below 100 mm, none above, "-" for NaN."""
    if value is None or not math.isfinite(value):
        return "-"
    return f"{value:.0f}" if abs(value) >= 99.95 else f"{value:.1f}"


def scale_of(*grids, symmetric: bool = False, at_least: float = 0.0) -> tuple[float, float]:
    """A colour scale over the finite values of ``grids``.

    Parameters
    ----------
    *grids : array-like
    symmetric : bool
        Centred on 0 (deviations): ``(-m, m)`` with ``m`` the largest magnitude.
    at_least : float
        Smallest half-width (symmetric) or width of the scale, so noise is not blown up.

    Returns
    -------
    (lo, hi) : float
    """
    values = np.concatenate([np.asarray(g, dtype=float).ravel() for g in grids]) if grids else np.array([])
    values = values[np.isfinite(values)]
    if symmetric:
        m = max(float(np.abs(values).max()) if values.size else 0.0, at_least, 1e-9)
        return -m, m
    if not values.size:
        return 0.0, max(at_least, 1.0)
    lo, hi = float(values.min()), float(values.max())
    if hi - lo < at_least:
        mid = 0.5 * (lo + hi)
        lo, hi = mid - 0.5 * at_least, mid + 0.5 * at_least
    return lo, hi


CELL = 40.0
"""The size of a heat map's cell in SVG units (the picture scales to its box)."""


def heat_map(values, *, lo: float, hi: float, cmap=VIRIDIS, id_prefix: str = "", flags=None, title: str = "",
             base: int = 1) -> str:
    """A punch matrix as an SVG heat map, row 1 at the bottom, with row and column numbers.

    Parameters
    ----------
    values : (rows, cols) float
        One value per punch (mm); NaN cells are grey and show "-".
    lo, hi : float
        Colour scale (see :func:`scale_of`).
    cmap : sequence of str
        :data:`VIRIDIS` (heights) or :data:`DIVERGING` (deviations).
    id_prefix : str
        When given, each cell is ``<rect id="{prefix}-r{R}-c{C}">`` and its value
        ``<text id="{prefix}-v-r{R}-c{C}">`` (R, C as named, i.e. ``base``-based), so a page can
        update them; cells carry ``data-name``.
    flags : (rows, cols) array of str, optional
        "" or a key of :data:`FLAG_COLOURS` per punch: the punch is outlined (and crossed when faulted).
    title : str
        Caption above the matrix.
    base : int
        First row / column number.

    Each punch's value is printed in its cell (:data:`CELL` units square).

    Returns
    -------
    str
        An ``<svg>`` element (viewBox, no fixed size).
    """
    grid = np.asarray(values, dtype=float)
    rows, cols = grid.shape
    cell = CELL
    pad_l, pad_b, pad_t = 1.3 * cell, 0.9 * cell, (0.9 * cell if title else 0.25 * cell)
    width, height = pad_l + cols * cell + 0.25 * cell, pad_t + rows * cell + pad_b
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {width:.0f} {height:.0f}" class="heat" '
           f'role="img" aria-label="{esc(title or "punch matrix")}" data-rows="{rows}" data-cols="{cols}">']
    if title:
        out.append(f'<text x="{pad_l:.1f}" y="{0.65 * cell:.1f}" class="map-title" font-size="{0.6 * cell:.1f}" '
                   f'font-weight="bold">{esc(title)}</text>')
    for r in range(rows):
        y = pad_t + (rows - 1 - r) * cell
        out.append(f'<text x="{pad_l - 0.15 * cell:.1f}" y="{y + 0.62 * cell:.1f}" text-anchor="end" '
                   f'font-size="{0.4 * cell:.1f}" class="axis">R{r + base}</text>')
        for c in range(cols):
            fill = colour(grid[r, c], lo, hi, cmap)
            ids = ((f"{esc(id_prefix)}-r{r + base}-c{c + base}", f"{esc(id_prefix)}-v-r{r + base}-c{c + base}")
                   if id_prefix else ("", ""))
            out.append(_cell(grid[r, c], fill, (pad_l + c * cell, y), punch_name(r, c, base), ids))
    for c in range(cols):
        out.append(f'<text x="{pad_l + (c + 0.5) * cell:.1f}" y="{pad_t + rows * cell + 0.6 * cell:.1f}" '
                   f'text-anchor="middle" font-size="{0.4 * cell:.1f}" class="axis">{c + base}</text>')
    out.append(_flag_marks(flags, rows, cell, pad_l, pad_t, id_prefix))
    out.append("</svg>")
    return "".join(out)


def _cell(v: float, fill: str, xy: tuple[float, float], name: str, ids: tuple[str, str]) -> str:
    """One punch's cell at ``xy`` (its top left, SVG units) with its value; ``ids`` of the cell and the value
    ("": none)."""
    x, y = xy
    cell = CELL
    vtext = value_text(v)
    rect_id, text_id = (f' id="{i}"' if i else "" for i in ids)
    return (f'<rect{rect_id} x="{x:.1f}" y="{y:.1f}" width="{cell:.1f}" height="{cell:.1f}" fill="{fill}" '
            f'stroke="#fff" stroke-width="{0.04 * cell:.1f}" class="cell" data-name="{name}" '
            f'data-mm="{f"{v:.2f}" if math.isfinite(v) else ""}"><title>{name}: {vtext} mm</title></rect>'
            f'<text{text_id} x="{x + 0.5 * cell:.1f}" y="{y + 0.62 * cell:.1f}" text-anchor="middle" '
            f'font-size="{0.34 * cell:.1f}" fill="{ink(fill)}" class="val">{vtext}</text>')


def _flag_marks(flags, rows: int, cell: float, pad_l: float, pad_t: float, id_prefix: str) -> str:
    """Outlines (and crosses) on the flagged punches, in a group a page can redraw."""
    gid = f' id="{esc(id_prefix)}-flags"' if id_prefix else ""
    out = [f'<g{gid} class="flags" data-cell="{cell:.1f}" data-left="{pad_l:.1f}" data-top="{pad_t:.1f}" '
           f'data-rows="{rows}">']
    if flags is not None:
        for (r, c), kind in np.ndenumerate(np.asarray(flags, dtype=object)):
            if kind:
                out.append(flag_mark(kind, r, c, rows, cell, pad_l, pad_t))
    out.append("</g>")
    return "".join(out)


def flag_mark(kind: str, r: int, c: int, rows: int, cell: float, pad_l: float, pad_t: float) -> str:
    """The mark of one flagged punch (0-based ``r``, ``c``): orange dashed ring, red ring and cross."""
    x, y = pad_l + c * cell, pad_t + (rows - 1 - r) * cell
    stroke = FLAG_COLOURS.get(kind, "#e00000")
    w = 0.14 * cell
    dash = f' stroke-dasharray="{0.25 * cell:.1f} {0.12 * cell:.1f}"' if kind != "faulted" else ""
    mark = (f'<rect x="{x + w / 2:.1f}" y="{y + w / 2:.1f}" width="{cell - w:.1f}" height="{cell - w:.1f}" '
            f'fill="none" stroke="{stroke}" stroke-width="{w:.1f}"{dash} class="flag flag-{esc(kind)}"/>')
    if kind == "faulted":
        mark += (f'<path d="M{x + w:.1f} {y + w:.1f}L{x + cell - w:.1f} {y + cell - w:.1f}M{x + cell - w:.1f} '
                 f'{y + w:.1f}L{x + w:.1f} {y + cell - w:.1f}" stroke="{stroke}" stroke-width="{w / 2:.1f}"/>')
    return mark


def legend(lo: float, hi: float, *, cmap=VIRIDIS, unit: str = "mm", label: str = "", width: float = 600.0,
           id_prefix: str = "") -> str:
    """A horizontal colour bar from ``lo`` to ``hi`` with its end values (ids ``{prefix}-lo`` / ``-hi``)."""
    h = 26.0
    stops = "".join(f'<stop offset="{k / (len(cmap) - 1):.3f}" stop-color="{c}"/>' for k, c in enumerate(cmap))
    gid = f"grad{zlib.crc32(repr((cmap, id_prefix, label)).encode()):08x}"
    lo_id = f' id="{esc(id_prefix)}-lo"' if id_prefix else ""
    hi_id = f' id="{esc(id_prefix)}-hi"' if id_prefix else ""
    return (f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {width:.0f} {h + 30:.0f}" class="legend" '
            f'role="img" aria-label="colour scale {esc(label)}">'
            f'<defs><linearGradient id="{gid}">{stops}</linearGradient></defs>'
            f'<rect x="0" y="0" width="{width:.0f}" height="{h:.0f}" fill="url(#{gid})" stroke="#444"/>'
            f'<text{lo_id} x="0" y="{h + 24:.0f}" font-size="22">{lo:.1f}</text>'
            f'<text x="{width / 2:.0f}" y="{h + 24:.0f}" font-size="22" text-anchor="middle">{esc(label)} ({esc(unit)})'
            f'</text><text{hi_id} x="{width:.0f}" y="{h + 24:.0f}" font-size="22" text-anchor="end">{hi:.1f}</text>'
            "</svg>")
