"""Stroke-map picture: both punch matrices side by side, tip heights in colour."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Polygon

from mppf.core.errors import InputError
from mppf.model.job import Job


def plot_strokes(job: Job, path, step: int | None = None) -> Path:
    """Draw the tip heights of one step (default: the last) and save a PNG.

    Upper and lower matrices are shown side by side, seen from above (press x to the
    right, y up); active punches as coloured squares (tip height, mm), inactive
    (parked) punches as grey crosses, the plate outline as a black line.

    Parameters
    ----------
    job : Job
    path : str or Path
        Output image (.png, .pdf or .svg).
    step : int, optional
        1-based step number.

    Returns
    -------
    Path
    """
    path = Path(path)
    index = len(job.steps) if step is None else int(step)
    if not 1 <= index <= len(job.steps):
        raise InputError(f"step {index} does not exist; the job has {len(job.steps)} step(s)")
    strokes = job.steps[index - 1]
    x, y = np.asarray(job.punch_x_mm), np.asarray(job.punch_y_mm)
    gx, gy = np.meshgrid(x, y)
    act = strokes.active
    pitch_x = job.press.pitch_x_mm
    pitch_y = job.press.pitch_y_mm
    outline = None if job.layout is None else job.layout.outline_mm
    fig = Figure(figsize=(13, 5.2), layout="constrained")
    axes = fig.subplots(1, 2)
    for ax, name, values, limits in ((axes[0], "upper", strokes.upper_mm, job.press.upper),
                                     (axes[1], "lower", strokes.lower_mm, job.press.lower)):
        shown = np.where(act, values, np.nan)
        edges_x = np.concatenate([x - pitch_x / 2, [x[-1] + pitch_x / 2]])
        edges_y = np.concatenate([y - pitch_y / 2, [y[-1] + pitch_y / 2]])
        mesh = ax.pcolormesh(edges_x, edges_y, np.ma.masked_invalid(shown), cmap="viridis",
                             edgecolors="white", linewidth=0.3)
        ax.plot(gx[~act], gy[~act], "x", color="0.6", markersize=4, label=f"parked ({limits.park_mm:g} mm)")
        if outline is not None:
            ax.add_patch(Polygon(np.asarray(outline), closed=True, fill=False, edgecolor="black", linewidth=1.5))
        ax.set_aspect("equal")
        ax.set_xlabel("press x (mm)")
        ax.set_ylabel("press y (mm)")
        vals = values[act]
        title = f"{name} matrix, step {index}/{len(job.steps)}"
        if vals.size:
            title += f": tips {vals.min():.1f} .. {vals.max():.1f} mm"
        ax.set_title(title)
        fig.colorbar(mesh, ax=ax, label=f"{name} tip height (mm)", shrink=0.85)
        ax.legend(loc="upper right", fontsize="small", framealpha=0.8)
    fig.suptitle(f"{job.press.name}: plate {job.thickness_mm:g} mm")
    try:
        fig.savefig(path, dpi=110)
    except (OSError, ValueError) as exc:
        raise InputError(f"cannot write the stroke map {path}: {exc}", hint="choose a writable .png path") from None
    return path
