"""Strain picture of an unfolding: the flat plate coloured by the in-plane strain.

The flat plate is drawn as it will be cut (x along its longer side, mm, seen from the
design's +n side), each point coloured by its in-plane strain in percent (smooth
shading over the triangles), with the outline in black, the strain limit as a red
contour where it is exceeded, the worst point marked and labelled, and arrows showing
where the design frame's +u and +v lie on the flat plate.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.tri import Triangulation

from mppf.core.errors import InputError
from mppf.geometry.mesh import boundary_edges
from mppf.geometry.unfold_report import Unfolding

CMAP = "magma_r"
"""Sequential colour map: pale = no strain, dark = most strain."""


def strain_figure(unfolding: Unfolding, title: str | None = None) -> Figure:
    """The strain picture as a matplotlib Figure (see the module docstring)."""
    u = unfolding
    x, y = u.flat[:, 0], u.flat[:, 1]
    tri = Triangulation(x, y, u.faces)
    fig = Figure(figsize=(10, 6.2), layout="constrained")
    ax = fig.subplots()
    top = max(u.max_strain_pct, 1e-6)
    shading = ax.tripcolor(tri, u.strain_pct, cmap=CMAP, shading="gouraud", vmin=0.0, vmax=top)
    if u.max_strain_pct > u.strain_limit_pct:
        ax.tricontour(tri, u.strain_pct, levels=[u.strain_limit_pct], colors="red", linewidths=1.2)
    outline = boundary_edges(u.faces)
    segments = np.stack([u.flat[outline[:, 0], :2], u.flat[outline[:, 1], :2]], axis=1)
    ax.add_collection(LineCollection(segments, colors="black", linewidths=1.0))
    wx, wy = x[u.worst_point], y[u.worst_point]
    ax.plot(wx, wy, marker="o", markersize=11, markerfacecolor="none", markeredgecolor="#00a0ff",
            markeredgewidth=2.2, linestyle="none",
            label=f"worst: {u.max_strain_pct:.3f} % at point {u.worst_point} ({u.worst_region})")
    _design_axes(ax, u)
    bar = fig.colorbar(shading, ax=ax, shrink=0.9)
    bar.set_label("in-plane strain (%)")
    if u.strain_limit_pct <= top:
        bar.ax.axhline(u.strain_limit_pct, color="red", linewidth=1.5)
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm, flat plate)")
    ax.set_ylabel("y (mm, flat plate)")
    width, height = np.ptp(x), np.ptp(y)
    verdict = "within" if u.max_strain_pct <= u.strain_limit_pct else "EXCEEDS"
    ax.set_title(title or f"Unfolded plate {width:.0f} x {height:.0f} mm: strain RMS {u.rms_strain_pct:.3f} %, "
                          f"max {u.max_strain_pct:.3f} % ({verdict} the {u.strain_limit_pct:g} % limit)",
                 fontsize=10)
    ax.legend(loc="upper right", fontsize=8)
    margin = 0.04 * max(width, height)
    ax.set_xlim(x.min() - margin, x.max() + margin)
    ax.set_ylim(y.min() - margin, y.max() + 3 * margin)
    return fig


def _design_axes(ax, u: Unfolding) -> None:
    """Arrows showing where the design frame's +u and +v lie on the flat plate."""
    rotation = u.tf_flat_design[:3, :3]
    size = 0.12 * float(np.ptp(u.flat[:, :2], axis=0).min())
    corner = u.flat[:, :2].min(axis=0) + 0.3 * size
    for name, axis in zip(("+u", "+v"), u.frame.axes[:2]):
        direction = (rotation @ axis)[:2]
        direction = direction / max(float(np.linalg.norm(direction)), 1e-12) * size
        ax.annotate("", xy=corner + direction, xytext=corner,
                    arrowprops={"arrowstyle": "->", "color": "#0060c0", "linewidth": 1.5})
        ax.text(*(corner + 1.6 * direction), f"design {name}", color="#0060c0", fontsize=8,
                ha="center", va="center")


def plot_strain(unfolding: Unfolding, path, title: str | None = None) -> Path:
    """Draw the strain picture and save it (.png, .pdf or .svg); return the path.

    Raises
    ------
    InputError
        The file cannot be written (missing folder, no permission, unknown type).
    """
    path = Path(path)
    try:
        strain_figure(unfolding, title).savefig(path, dpi=120)
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot write the strain picture {path}: {getattr(exc, 'strerror', None) or exc}",
                         hint="give a .png, .pdf or .svg path in a writable folder") from None
    return path
