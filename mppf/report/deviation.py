"""Deviation pictures of a comparison: a colour map on the design plate, a histogram.

The map shows the design plate in its own frame (u along its longest extent, v across,
seen from the +normal side): the measured points coloured by their signed deviation
with a diverging colour map centred on 0 (blue below the design, red above) on a FIXED
scale (default +-2 x the tolerance, :func:`colour_limit_mm`: the same for every cycle of a
plate, so pictures compare), the tolerance as black contour lines, set-aside points as
black crosses and the design outline; areas without scan data are hatched, and the areas
of the net plate not measured within the allowed gap (:mod:`mppf.measure.coverage`) are
outlined in magenta, cross-hatched and numbered. With a trim
margin, the points in the margin are grey dots (not counted) inside the grown outline
(dashed). The punch map names rows and columns as the press does (from 1 by default) and
writes each punch's value in its cell.
"""

from __future__ import annotations

import io
import textwrap
from pathlib import Path

import numpy as np
from matplotlib.colors import TwoSlopeNorm
from matplotlib.figure import Figure
from matplotlib.tri import Triangulation

from mppf.core.polygon import convex_outline, offset_convex
from mppf.measure.punches import short_label
from mppf.measure.result import Comparison

CMAP = "RdBu_r"
"""Diverging colour map: blue = below the design, red = above."""


SCALE_TOLERANCES = 2.0
"""Default half range of the colour scale, in tolerances."""

HATCH = "////"
"""Hatching of areas without data (not scanned, punches off the scan)."""


def colour_limit_mm(comparison: Comparison, scale_mm: float | None = None) -> float:
    """Half range (mm) of the colour scale: ``scale_mm``, default :data:`SCALE_TOLERANCES` x the tolerance."""
    return float(scale_mm) if scale_mm is not None else SCALE_TOLERANCES * comparison.tolerance_mm


def _triangulation(uv: np.ndarray) -> Triangulation | None:
    """Delaunay triangulation of the points without the long triangles spanning scan gaps."""
    if uv.shape[0] < 10:
        return None
    try:
        tri = Triangulation(uv[:, 0], uv[:, 1])
    except (ValueError, RuntimeError):  # degenerate (collinear) points
        return None
    corners = uv[tri.triangles]
    edges = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2).max(axis=1)
    tri.set_mask(edges > 4.0 * np.median(edges))
    return tri


def deviation_map_figure(comparison: Comparison, title: str | None = None, scale_mm: float | None = None) -> Figure:
    """The colour deviation map as a matplotlib Figure (see the module docstring); ``scale_mm``: the colour
    scale's half range (default :func:`colour_limit_mm`)."""
    c = comparison
    uv = c.measured_uv_mm
    inl = c.inlier
    limit = colour_limit_mm(c, scale_mm)
    fig = Figure(figsize=(10, 6.2), layout="constrained")
    ax = fig.subplots()
    outline = convex_outline(c.design_uv_mm, "the design")
    ring = np.vstack([outline, outline[:1]])
    ax.fill(ring[:, 0], ring[:, 1], facecolor="white", edgecolor="0.55", hatch=HATCH, linewidth=0.0, zorder=0,
            label="no scan data")
    ax.plot(ring[:, 0], ring[:, 1], color="black", linestyle="-", linewidth=1.2, zorder=4)
    if c.margin_mm > 0:
        grown = offset_convex(outline, c.margin_mm)
        grown = np.vstack([grown, grown[:1]])
        ax.plot(grown[:, 0], grown[:, 1], color="0.4", linestyle="--", linewidth=0.9, zorder=4)
        if c.in_margin.any():
            ax.plot(uv[c.in_margin, 0], uv[c.in_margin, 1], ".", color="0.6", markersize=2, zorder=1,
                    label=f"trim margin {c.margin_mm:g} mm ({int(c.in_margin.sum())} points, not counted)")
    norm = TwoSlopeNorm(vcenter=0.0, vmin=-limit, vmax=limit)
    d = c.deviation_mm[inl]
    tri = _triangulation(uv[inl])
    if tri is not None:
        # a continuous colour field over the scanned area (gaps of the scan stay grey)
        sc = ax.tripcolor(tri, d, cmap=CMAP, norm=norm, shading="gouraud", zorder=2)
        if d.min() < -c.tolerance_mm or d.max() > c.tolerance_mm:
            ax.tricontour(tri, d, levels=[-c.tolerance_mm, c.tolerance_mm], colors="black", linewidths=0.9,
                          linestyles=["--", "-"], zorder=3)
    else:
        sc = ax.scatter(uv[inl, 0], uv[inl, 1], c=d, cmap=CMAP, norm=norm, s=12, linewidths=0, zorder=2)
    extra = []  # legend entries drawn without a label of their own
    if c.coverage is not None and c.coverage.uncovered.any():
        extra.append(_draw_uncovered(ax, c.coverage))
    if c.is_outlier.any():
        ax.plot(uv[c.is_outlier, 0], uv[c.is_outlier, 1], "x", color="black", markersize=4, zorder=4,
                label=f"set aside as scanner artefacts ({int(c.is_outlier.sum())}, reported)")
    bar = fig.colorbar(sc, ax=ax, shrink=0.9, extend="both")
    bar.set_label(f"deviation along the design normal (mm, fixed scale +-{limit:g})")
    for level in (-c.tolerance_mm, c.tolerance_mm):
        bar.ax.axhline(level, color="black", linewidth=1.2)
    ax.set_aspect("equal")
    ax.set_xlabel("u (mm, design frame)")
    ax.set_ylabel("v (mm, design frame)")
    ax.set_title(title or f"{textwrap.fill(c.headline, 125)}\nlargest point |d| {c.max_abs_mm:.2f} mm, "
                          f"{c.within_tolerance_pct:.1f} % of the net points within +-{c.tolerance_mm:g} mm",
                 fontsize=9)
    handles, _ = ax.get_legend_handles_labels()
    ax.legend(handles=handles + extra, loc="upper right", fontsize=8)
    return fig


def _draw_uncovered(ax, coverage):
    """Draw the areas of the net plate not measured (:mod:`mppf.measure.coverage`): outlined in magenta,
    cross-hatched, each numbered as listed (the largest first); return their legend entry."""
    from matplotlib.patches import Patch

    mask = coverage.uncovered.astype(float)
    ax.contourf(coverage.grid_u_mm, coverage.grid_v_mm, mask, levels=[0.5, 1.5], colors="none", hatches=["xx"],
                zorder=3)
    ax.contour(coverage.grid_u_mm, coverage.grid_v_mm, mask, levels=[0.5], colors="magenta", linewidths=1.4, zorder=4)
    for number, gap in enumerate(coverage.regions[:9], start=1):
        ax.annotate(f"{number}", gap.centroid_uv_mm, color="magenta", fontsize=10, fontweight="bold", ha="center",
                    va="center", zorder=5, bbox={"facecolor": "white", "edgecolor": "magenta", "boxstyle": "circle"})
    return Patch(facecolor="none", edgecolor="magenta", hatch="xx",
                 label=f"not measured: {len(coverage.regions)} area(s), gaps wider than "
                       f"{coverage.allowed_gap_mm:.0f} mm (needs review)")


def histogram_figure(comparison: Comparison) -> Figure:
    """Histogram of the inlier deviations with the tolerance band, as a Figure."""
    c = comparison
    edges, counts = c.histogram_edges_mm, c.histogram_counts
    fig = Figure(figsize=(8, 3.6), layout="constrained")
    ax = fig.subplots()
    centres = 0.5 * (edges[1:] + edges[:-1])
    inside = np.abs(centres) <= c.tolerance_mm
    ax.bar(centres, counts, width=np.diff(edges), color=np.where(inside, "#4c72b0", "#c44e52"),
           edgecolor="white", linewidth=0.5)
    ax.axvspan(-c.tolerance_mm, c.tolerance_mm, color="green", alpha=0.08, label=f"tolerance +-{c.tolerance_mm:g} mm")
    ax.axvline(0.0, color="black", linewidth=0.8)
    ax.set_xlabel("deviation (mm)")
    ax.set_ylabel("points")
    ax.set_title(f"{c.n_inliers} points, mean {c.mean_mm:+.2f} mm, RMS {c.rms_mm:.2f} mm", fontsize=10)
    ax.legend(fontsize=8)
    return fig


def punch_map_figure(comparison: Comparison, punch_x_mm, punch_y_mm, scale_mm: float | None = None) -> Figure:
    """Deviation at each punch (press z) on the punch grid, the value written in each cell; rows and columns
    named as the press names them (``Comparison.punch_label_base``); interpolated punches hatched."""
    c = comparison
    x, y = np.asarray(punch_x_mm, dtype=float), np.asarray(punch_y_mm, dtype=float)
    values = np.ma.masked_invalid(c.punch_deviation_mm)
    limit = colour_limit_mm(c, scale_mm)
    fig = Figure(figsize=(max(10, 0.55 * x.size), max(5.5, 0.45 * y.size)), layout="constrained")
    ax = fig.subplots()
    dx = np.diff(x).mean() if x.size > 1 else 1.0
    dy = np.diff(y).mean() if y.size > 1 else 1.0
    edges_x = np.concatenate([x - dx / 2, [x[-1] + dx / 2]])
    edges_y = np.concatenate([y - dy / 2, [y[-1] + dy / 2]])
    mesh = ax.pcolormesh(edges_x, edges_y, values, cmap=CMAP, norm=TwoSlopeNorm(0.0, -limit, limit),
                         edgecolors="white", linewidth=0.3)
    base = c.punch_label_base
    interp = c.punch_interpolated
    for i, j in zip(*np.nonzero(np.isfinite(c.punch_deviation_mm))):
        # inside the axes: left out of the layout (which would measure every label on every pass: most of the time)
        ax.text(x[j], y[i], f"{c.punch_deviation_mm[i, j]:+.1f}", ha="center", va="center", fontsize=5.5,
                in_layout=False)
        if interp[i, j]:
            ax.add_patch(_cell_patch(x[j], y[i], dx, dy))
    gx, gy = np.meshgrid(x, y)
    ax.plot(gx[interp], gy[interp], "o", markerfacecolor="none", markeredgecolor="black", markersize=9,
            label="interpolated (no scan data)")
    ax.set_xticks(x, [str(j + base) for j in range(x.size)], fontsize=6)
    ax.set_yticks(y, [str(i + base) for i in range(y.size)], fontsize=6)
    fig.colorbar(mesh, ax=ax, label=f"plate deviation along press z (mm, fixed scale +-{limit:g})", extend="both")
    ax.set_aspect("equal")
    ax.set_xlabel(f"punch column (from {base}; press x)")
    ax.set_ylabel(f"punch row (from {base}; press y)")
    ax.set_title(f"Deviation at the punches (positive = plate above the design; hatched = interpolated, no scan data; "
                 f"e.g. punch {short_label(0, 0, base)} = row {base}, col {base})", fontsize=9)
    if interp.any():
        ax.legend(fontsize=8, loc="upper right")
    return fig


def _cell_patch(x: float, y: float, dx: float, dy: float):
    from matplotlib.patches import Rectangle

    return Rectangle((x - dx / 2, y - dy / 2), dx, dy, fill=False, hatch=HATCH, edgecolor="0.3", linewidth=0.0)


def figure_png(fig: Figure, dpi: int = 110) -> bytes:
    """PNG bytes of a figure (for embedding in the HTML report)."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    return buffer.getvalue()


def plot_deviation(comparison: Comparison, path, title: str | None = None, scale_mm: float | None = None) -> Path:
    """Draw the colour deviation map and save it (.png, .pdf or .svg); return the path."""
    path = Path(path)
    deviation_map_figure(comparison, title, scale_mm).savefig(path, dpi=120)
    return path


def plot_histogram(comparison: Comparison, path) -> Path:
    """Draw the deviation histogram and save it; return the path."""
    path = Path(path)
    histogram_figure(comparison).savefig(path, dpi=120)
    return path
