"""Where to lay the plate, drawn: the bed to scale with the plate as cut, its mark and its corners.

The corners and the mark (:class:`~mppf.model.placement.Placement`,
:func:`~mppf.model.placement.placement_of`) are :mod:`mppf.model.placement`, where ``mppf press``
and ``mppf loop`` take them too (:mod:`mppf.cli._placement`). :func:`bed_svg` draws the bed to
scale with the punches (those of the step about to be pressed filled), the plate as cut, its net
outline, the mark and the lettered corners with their press coordinates, for the panel's "Lay the
plate" view. Pure: arrays in, SVG text out.
"""

from __future__ import annotations

import numpy as np

from mppf.model.placement import Placement
from mppf.model.press import PressConfig
from mppf.panel.svg import esc


def bed_svg(press: PressConfig, placement: Placement | None, *, active=None, base: int = 1,
            font_mm: float | None = None) -> str:
    """The bed seen from above, to scale, with the plate where it must lie.

    Parameters
    ----------
    press : PressConfig
    placement : Placement or None
        None: the bed alone.
    active : (rows, cols) bool, optional
        Punches of the step about to be pressed (filled).
    base : int
        First row / column number.
    font_mm : float, optional
        Label size in mm of the drawing (default: from the bed size).

    Returns
    -------
    str
        An ``<svg>`` in press mm (x right, y up), scaling to its box.
    """
    xs, ys = press.punch_x_mm, press.punch_y_mm
    bed = np.array([xs.min() - press.pitch_x_mm / 2, ys.min() - press.pitch_y_mm / 2,
                    xs.max() + press.pitch_x_mm / 2, ys.max() + press.pitch_y_mm / 2])
    font = font_mm or 0.026 * (bed[2] - bed[0])
    x0, y0, x1, y1 = _extent(bed, placement, font)
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="{x0:.0f} {-y1:.0f} {x1 - x0:.0f} {y1 - y0:.0f}" '
           f'class="bed" role="img" aria-label="the press bed seen from above, with the plate to lay">',
           f'<rect x="{bed[0]:.0f}" y="{-bed[3]:.0f}" width="{bed[2] - bed[0]:.0f}" height="{bed[3] - bed[1]:.0f}" '
           f'fill="#eef1f4" stroke="#333" stroke-width="{font / 8:.1f}"/>',
           _punches(press, active, font, base)]
    if placement is not None:
        out.append(_plate(placement, font))
    out.append(_origin(font))
    out.append("</svg>")
    return "".join(out)


def _extent(bed, placement: Placement | None, font: float) -> tuple[float, float, float, float]:
    """The drawing's bounds: bed and outlines, with room for the labels."""
    pts = [bed[:2], bed[2:]]
    if placement is not None:
        pts += list(placement.cut_outline_mm)
    pts = np.array(pts)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    return lo[0] - 3.2 * font, lo[1] - 2.9 * font, hi[0] + 1.0 * font, hi[1] + 1.2 * font


def _punches(press: PressConfig, active, font: float, base: int) -> str:
    """Every punch as a ball-sized circle (active ones filled) and the row and column numbers."""
    act = np.zeros(press.shape, bool) if active is None else np.asarray(active, dtype=bool)
    xs, ys = press.punch_x_mm, press.punch_y_mm
    out = ['<g class="punches">']
    for r, y in enumerate(ys):
        for c, x in enumerate(xs):
            fill, stroke = ("#7a99b8", "#4d6f91") if act[r, c] else ("#ffffff", "#9aa5b1")
            out.append(f'<circle cx="{x:.0f}" cy="{-y:.0f}" r="{press.tip_radius_mm:.0f}" fill="{fill}" '
                       f'stroke="{stroke}" stroke-width="{font / 12:.1f}"/>')
    bottom = ys.min() - press.pitch_y_mm / 2 - 0.35 * font
    left = xs.min() - press.pitch_x_mm / 2 - 0.35 * font
    for c, x in enumerate(xs):
        out.append(f'<text x="{x:.0f}" y="{-bottom + 0.9 * font:.0f}" font-size="{0.75 * font:.0f}" '
                   f'text-anchor="middle" class="axis">{c + base}</text>')
    for r, y in enumerate(ys):
        out.append(f'<text x="{left:.0f}" y="{-y + 0.28 * font:.0f}" font-size="{0.75 * font:.0f}" '
                   f'text-anchor="end" class="axis">R{r + base}</text>')
    out.append(f'<text x="{xs.min() - press.pitch_x_mm / 2:.0f}" y="{-bottom + 1.9 * font:.0f}" '
               f'font-size="{0.75 * font:.0f}" class="axis">columns (x) &#8594;</text>')
    out.append("</g>")
    return "".join(out)


def _points(poly) -> str:
    return " ".join(f"{x:.1f},{-y:.1f}" for x, y in np.asarray(poly, dtype=float))


def _plate(p: Placement, font: float) -> str:
    """The plate as cut (filled), its net outline (dashed), the mark and the lettered corners."""
    out = [f'<polygon points="{_points(p.cut_outline_mm)}" fill="#b9c2cc" fill-opacity="0.78" stroke="#1f2d3a" '
           f'stroke-width="{font / 5:.1f}" class="cut-outline"/>',
           f'<polygon points="{_points(p.net_outline_mm)}" fill="none" stroke="#1f2d3a" '
           f'stroke-width="{font / 8:.1f}" stroke-dasharray="{font / 1.5:.0f} {font / 3:.0f}" class="net-outline"/>']
    centre = p.cut_outline_mm.mean(axis=0)
    for k, (name, (x, y)) in enumerate(zip(p.corner_names, p.cut_corners_mm)):
        # the label above a top corner, below a bottom one, running inwards: clear of the mark and the plate
        sx = 1.0 if x < centre[0] else -1.0
        tx, ty = x - sx * 0.2 * font, y + (0.55 * font if y > centre[1] else -1.3 * font)
        cls = "corner corner-mark" if k == 0 else "corner"
        coords = f" {x:.0f}, {y:.0f}"
        w = (0.8 + 0.6 * len(coords)) * font  # about the label's width, for its white backing
        bx = tx - 0.1 * font if sx > 0 else tx - w + 0.1 * font
        out.append(f'<circle cx="{x:.1f}" cy="{-y:.1f}" r="{0.3 * font:.0f}" fill="#1f2d3a" class="{cls}"/>')
        out.append(f'<rect x="{bx:.0f}" y="{-ty - 1.05 * font:.0f}" width="{w:.0f}" height="{1.35 * font:.0f}" '
                   f'fill="#fff" fill-opacity="0.85" rx="{0.15 * font:.0f}"/>')
        anchor = "start" if sx > 0 else "end"
        out.append(f'<text x="{tx:.0f}" y="{-ty:.0f}" font-size="{font:.0f}" text-anchor="{anchor}" '
                   f'class="{cls}-label" data-corner="{name}"><tspan font-weight="bold" font-size="{1.3 * font:.0f}">'
                   f'{name}</tspan>{coords}</text>')
    mx, my = p.mark_mm
    s = 0.55 * font
    out.append(f'<path d="M{mx:.0f} {-my - s:.0f}L{mx + s:.0f} {-my:.0f}L{mx:.0f} {-my + s:.0f}L{mx - s:.0f} '
               f'{-my:.0f}Z" fill="#d62728" stroke="#fff" stroke-width="{font / 10:.1f}" class="mark"/>')
    out.append(f'<text x="{mx + 0.8 * font:.0f}" y="{-my - 0.35 * font:.0f}" font-size="{0.85 * font:.0f}" '
               f'fill="#b01c1c" font-weight="bold" paint-order="stroke" stroke="#fff" stroke-width="{font / 5:.0f}">'
               f'{esc("MARK")}</text>')
    return "".join(out)


def _origin(font: float) -> str:
    """The press origin (centre of the matrix) as a small cross."""
    s = 0.4 * font
    return (f'<path d="M{-s:.0f} 0L{s:.0f} 0M0 {-s:.0f}L0 {s:.0f}" stroke="#d62728" stroke-width="{font / 10:.1f}"/>'
            f'<text x="{0.3 * font:.0f}" y="{0.8 * font:.0f}" font-size="{0.6 * font:.0f}" fill="#b01c1c">0, 0</text>')
