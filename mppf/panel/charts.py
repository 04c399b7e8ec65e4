"""SVG charts of a plate's loop: the convergence of its deviations over the cycles.

Pure: numbers in, SVG text out (see :mod:`mppf.panel.svg`), for the panel's loop view and
the per-plate report.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from mppf.panel.svg import esc

MAX_COLOUR = "#b42318"
RMS_COLOUR = "#1f4e8c"

MARGINS = (90.0, 30.0, 56.0, 70.0)
"""The plotting area's distance from the left, right, top and bottom of the chart (SVG units)."""


def convergence_svg(cycles, max_abs_mm, rms_mm, *, tolerance_mm: float | None = None,
                    rms_tolerance_mm: float | None = None, width: float = 640.0, height: float = 420.0) -> str:
    """Largest |deviation| and RMS per cycle, with their tolerances as dashed lines.

    Parameters
    ----------
    cycles : sequence of int
        Cycle numbers (x).
    max_abs_mm, rms_mm : sequence of float or None
        Per cycle; None or NaN for a cycle not yet measured (left out).
    tolerance_mm, rms_tolerance_mm : float, optional
        The loop's tolerances (horizontal lines).
    width, height : float
        Size in SVG units (the chart scales to its box).

    Returns
    -------
    str
        An ``<svg>`` element.
    """
    pts = [(int(c), _num(m), _num(r)) for c, m, r in zip(cycles, max_abs_mm, rms_mm)]
    measured = [p for p in pts if p[1] is not None or p[2] is not None]
    left, top = MARGINS[0], MARGINS[2]
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {width:.0f} {height:.0f}" class="chart" '
           'role="img" aria-label="convergence of the deviations over the cycles">']
    out.append(f'<text x="{left - 10:.0f}" y="{top - 14:.0f}" font-size="22" text-anchor="end">mm</text>')
    if not measured:
        out.append(f'<text x="{width / 2:.0f}" y="{height / 2:.0f}" font-size="28" text-anchor="middle">'
                   "no cycle measured yet</text></svg>")
        return "".join(out)
    values = [v for p in measured for v in p[1:] if v is not None] + [t for t in (tolerance_mm, rms_tolerance_mm) if t]
    c_lo = min(p[0] for p in pts)
    plot = _Plot(width, height, _nice_ceiling(max(values) * 1.1), c_lo, max(max(p[0] for p in pts), c_lo + 1))
    out.append(plot.axes())
    out += plot.tolerance_lines(tolerance_mm, rms_tolerance_mm)
    out += plot.series(measured)
    out.append(f'<g font-size="22"><rect x="{left:.0f}" y="14" width="28" height="8" fill="{MAX_COLOUR}"/>'
               f'<text x="{left + 36:.0f}" y="25">largest |deviation|</text>'
               f'<rect x="{left + 260:.0f}" y="14" width="28" height="8" fill="{RMS_COLOUR}"/>'
               f'<text x="{left + 296:.0f}" y="25">RMS</text></g>')
    out.append("</svg>")
    return "".join(out)


@dataclass(frozen=True)
class _Plot:
    """The convergence chart's plotting area: SVG size, the value range (0 to ``y_hi`` mm) and the cycle range."""

    width: float
    height: float
    y_hi: float
    c_lo: int
    c_hi: int
    left: float = MARGINS[0]
    right: float = MARGINS[1]
    top: float = MARGINS[2]
    bottom: float = MARGINS[3]

    def sx(self, c) -> float:
        """The x of cycle ``c``."""
        return self.left + (c - self.c_lo) / (self.c_hi - self.c_lo) * (self.width - self.left - self.right)

    def sy(self, v) -> float:
        """The y of ``v`` mm."""
        return self.height - self.bottom - v / self.y_hi * (self.height - self.top - self.bottom)

    def axes(self) -> str:
        """Frame, y grid lines with values, cycle numbers along x."""
        left, right, top, bottom, width, height, sy = (self.left, self.right, self.top, self.bottom, self.width,
                                                       self.height, self.sy)
        out = [f'<rect x="{left:.0f}" y="{top:.0f}" width="{width - left - right:.0f}" '
               f'height="{height - top - bottom:.0f}" fill="#fff" stroke="#555"/>']
        for k in range(6):
            v = self.y_hi * k / 5
            out.append(f'<line x1="{left:.0f}" x2="{width - right:.0f}" y1="{sy(v):.1f}" y2="{sy(v):.1f}" '
                       f'stroke="#ddd"/><text x="{left - 10:.0f}" y="{sy(v) + 7:.1f}" font-size="20" '
                       f'text-anchor="end">{v:g}</text>')
        for c in range(self.c_lo, self.c_hi + 1):
            out.append(f'<text x="{self.sx(c):.1f}" y="{height - bottom + 30:.0f}" font-size="22" '
                       f'text-anchor="middle">{c}</text>')
        out.append(f'<text x="{(left + width - right) / 2:.0f}" y="{height - 12:.0f}" font-size="22" '
                   'text-anchor="middle">cycle</text>')
        return "".join(out)

    def tolerance_lines(self, tolerance_mm, rms_tolerance_mm) -> list[str]:
        """The tolerances as dashed lines, labelled at opposite ends (the two labels never overlap)."""
        out = []
        ends = ((self.width - self.right - 6, "end"), (self.left + 6, "start"))
        for (tol, colour, name), (x, anchor) in zip(((tolerance_mm, MAX_COLOUR, "tolerance"),
                                                     (rms_tolerance_mm, RMS_COLOUR, "RMS tolerance")), ends):
            if tol:
                y = self.sy(tol)
                out.append(f'<line x1="{self.left:.0f}" x2="{self.width - self.right:.0f}" y1="{y:.1f}" '
                           f'y2="{y:.1f}" stroke="{colour}" stroke-width="2" stroke-dasharray="10 7"/>'
                           f'<text x="{x:.0f}" y="{y - 8:.1f}" font-size="20" text-anchor="{anchor}" '
                           f'fill="{colour}">{esc(name)} {tol:g}</text>')
        return out

    def series(self, measured) -> list[str]:
        """The largest |deviation| and the RMS per measured cycle: lines and dots."""
        out = []
        for index, colour in ((1, MAX_COLOUR), (2, RMS_COLOUR)):
            line = [(self.sx(p[0]), self.sy(p[index])) for p in measured if p[index] is not None]
            if len(line) > 1:
                out.append(f'<polyline points="{" ".join(f"{x:.1f},{y:.1f}" for x, y in line)}" fill="none" '
                           f'stroke="{colour}" stroke-width="4"/>')
            out += [f'<circle cx="{x:.1f}" cy="{y:.1f}" r="7" fill="{colour}"/>' for x, y in line]
        return out


def _num(value) -> float | None:
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def _nice_ceiling(value: float) -> float:
    """1, 2, 2.5 or 5 times a power of ten, at least ``value``."""
    if value <= 0:
        return 1.0
    power = 10 ** math.floor(math.log10(value))
    for f in (1.0, 2.0, 2.5, 5.0, 10.0):
        if f * power >= value:
            return f * power
    return 10 * power
