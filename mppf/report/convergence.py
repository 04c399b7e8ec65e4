"""Pictures and the HTML report of a bend - measure - compare loop.

:func:`convergence_figure` plots the largest absolute and the RMS deviation of every
cycle against the two limits; :func:`loop_report` is one self-contained HTML page with
the cycle table, the convergence chart, pictures of the plate and of each cycle (built
from :mod:`mppf.report.html`'s building blocks); :func:`demo_report` draws everything of a
demo run (:func:`mppf.loop.demo.run_demo`).
"""

from __future__ import annotations

import html
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from mppf.loop.records import CycleRecord, PlateRecord
from mppf.report.html import image_html, render_page, table_html
from mppf.report.parallel import Task, draw
from mppf.report.deviation import figure_png, punch_map_figure


def convergence_figure(cycles: Sequence[CycleRecord], tolerance_mm: float, rms_tolerance_mm: float) -> Figure:
    """Largest absolute and RMS deviation per cycle, with the limits as dashed lines."""
    measured = [c for c in cycles if c.max_abs_mm is not None]
    n = [c.cycle for c in measured]
    fig = Figure(figsize=(6.5, 4), layout="constrained")
    ax = fig.subplots()
    ax.plot(n, [c.max_abs_mm for c in measured], "o-", color="tab:red", label="largest |deviation|")
    ax.plot(n, [c.rms_mm for c in measured], "s-", color="tab:blue", label="RMS deviation")
    ax.axhline(tolerance_mm, color="tab:red", linestyle="--", linewidth=1, label=f"limit {tolerance_mm:g} mm")
    ax.axhline(rms_tolerance_mm, color="tab:blue", linestyle="--", linewidth=1,
               label=f"RMS limit {rms_tolerance_mm:g} mm")
    ax.set_xlabel("press cycle")
    ax.set_ylabel("deviation from the design (mm)")
    ax.set_xticks(n or [1])
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Convergence of the loop", fontsize=10)
    return fig


def plot_convergence(cycles: Sequence[CycleRecord], path, tolerance_mm: float, rms_tolerance_mm: float) -> Path:
    """Draw :func:`convergence_figure` and save it; return the path."""
    path = Path(path)
    convergence_figure(cycles, tolerance_mm, rms_tolerance_mm).savefig(path, dpi=120)
    return path


def plot_punch_deviation(comparison, punch_x_mm, punch_y_mm, path) -> Path:
    """Draw the deviation at the punches of a comparison and save it; return the path."""
    path = Path(path)
    punch_map_figure(comparison, punch_x_mm, punch_y_mm).savefig(path, dpi=110)
    return path


def cycle_rows(cycles: Sequence[CycleRecord]) -> list[tuple]:
    """One row per cycle: cycle, steps, form max, RMS, within %, gain, decision, scan SHA-256."""
    return [
        (c.cycle, f"{c.steps_done}/{len(c.steps)}" + (" (interrupted)" if c.interrupted else ""),
         np.nan if c.max_abs_mm is None else c.max_abs_mm, np.nan if c.rms_mm is None else c.rms_mm,
         np.nan if c.within_pct is None else c.within_pct, np.nan if c.gain is None else c.gain,
         c.decision or c.state, (c.scan_sha256 or "")[:12])
        for c in cycles
    ]


CYCLE_HEADER = ("cycle", "steps", "form max (mm)", "RMS (mm)", "within tolerance (%)", "gain", "decision",
                "scan SHA-256")


def loop_report(
    plate: PlateRecord,
    cycles: Sequence[CycleRecord],
    *,
    tolerance_mm: float,
    rms_tolerance_mm: float,
    pictures: Sequence[tuple[str, bytes]] = (),
    cycle_pictures: Mapping[int, Sequence[tuple[str, bytes]]] | None = None,
    intro: str = "",
    details: Sequence[tuple[str, object]] = (),
) -> str:
    """The HTML report of a plate's loop.

    Parameters
    ----------
    plate : PlateRecord
    cycles : sequence of CycleRecord
    tolerance_mm, rms_tolerance_mm : float
    pictures : sequence of (caption, png bytes)
        Pictures of the plate (strain, strokes...).
    cycle_pictures : mapping cycle -> sequence of (caption, png bytes)
        Pictures of each cycle (deviation map, deviation at the punches).
    intro : str
    details : sequence of (name, value)
        More rows of the summary (the production report: date, operator, press, job hashes).

    Returns
    -------
    str
        The HTML document.
    """
    status = plate.status if plate.status != "active" else "running"
    summary = table_html([
        ("plate", plate.plate_id), ("result", status), ("design", f"{plate.design_path} ({plate.design_sha256[:12]})"),
        ("flat", f"{plate.flat_path} ({plate.flat_sha256[:12]})"), ("thickness (mm)", plate.thickness_mm),
        ("limits", f"form max <= {tolerance_mm:g} mm and RMS <= {rms_tolerance_mm:g} mm"),
        *details,
    ])
    sections = [("Summary", summary + table_html(cycle_rows(cycles), CYCLE_HEADER)),
                ("Convergence", image_html(figure_png(convergence_figure(cycles, tolerance_mm, rms_tolerance_mm)),
                                           "convergence"))]
    if pictures:
        sections.append(("Plate and strokes", _figures(pictures)))
    for number, shots in sorted((cycle_pictures or {}).items()):
        sections.append((f"Cycle {number}", _figures(shots)))
    return render_page(f"Bend - measure - compare: plate {plate.plate_id}", sections, intro)


def _figures(pictures: Sequence[tuple[str, bytes]]) -> str:
    return "\n".join(image_html(png, caption) + f"<p>{html.escape(caption)}</p>" for caption, png in pictures)


def draw_pictures(first: Sequence[Task], comparisons: Mapping[int, object], job, out: Path,
                  cycles: Sequence[CycleRecord], limits: Mapping[str, float],
                  captions: Callable[[int], tuple[str, str]]) -> tuple[list[Path], dict[int, list[tuple[str, bytes]]]]:
    """Draw a report's pictures on more than one core (:func:`mppf.report.parallel.draw`).

    Parameters
    ----------
    first : sequence of (function, args)
        Pictures before the cycles' (strain, strokes), each function returning its path.
    comparisons : mapping cycle -> Comparison
        Each gets a deviation map ``deviation-cycle-N.png`` and a punch map ``punch-deviation-cycle-N.png``.
    job : Job
        Its punch grid (the punch maps).
    out : Path
        The folder.
    cycles : sequence of CycleRecord
        For the convergence chart ``convergence.png``.
    limits : mapping
        ``tolerance_mm`` and ``rms_tolerance_mm``.
    captions : callable
        Cycle number -> (the deviation map's title, the punch map's caption).

    Returns
    -------
    paths : list of Path
        ``first``'s pictures, each cycle's map and punch map, the convergence chart.
    cycle_pictures : dict
        Cycle -> [(caption, png bytes)] of its two pictures (for :func:`loop_report`).
    """
    from mppf.report.deviation import plot_deviation

    tasks = list(first)
    numbers = sorted(comparisons)
    for n in numbers:
        tasks += [(plot_deviation, (comparisons[n], out / f"deviation-cycle-{n}.png", captions(n)[0])),
                  (plot_punch_deviation, (comparisons[n], job.punch_x_mm, job.punch_y_mm,
                                          out / f"punch-deviation-cycle-{n}.png"))]
    tasks.append((plot_convergence, (cycles, out / "convergence.png", limits["tolerance_mm"],
                                     limits["rms_tolerance_mm"])))
    paths = draw(tasks)
    at = len(first)
    cycle_pictures = {n: [(caption, path.read_bytes()) for caption, path in zip(captions(n), paths[at + 2 * k:])]
                      for k, n in enumerate(numbers)}
    return paths, cycle_pictures


def demo_report(run, intro: str) -> list[Path]:
    """The pictures and the HTML report of a demo run, written into its folder.

    Parameters
    ----------
    run : mppf.loop.demo.DemoRun
    intro : str
        The report's first paragraph (what ran: which press, how fast).

    Returns
    -------
    list of Path
        The flat shape, the strain and strokes pictures, the deviation pictures of each
        cycle, the convergence chart and ``report.html``, in that order.
    """
    from mppf.report.strain import plot_strain
    from mppf.report.strokes import plot_strokes

    out, job = run.out, run.job
    limits = {"tolerance_mm": run.settings.tolerance_mm, "rms_tolerance_mm": run.settings.rms_tolerance_mm}
    first = [(plot_strain, (run.unfolding, out / "strain.png", f"{run.plate_name}: strain of the unfolding")),
             (plot_strokes, (job, out / "strokes.png"))]
    drawn, cycle_pictures = draw_pictures(
        first, run.comparisons, job, out, run.result.cycles, limits,
        lambda n: (f"cycle {n}: deviation of the scan from the design", f"cycle {n}: deviation at the punches"))
    files = [run.flat_path, *([run.flat_dxf_path] if run.flat_dxf_path else []), *drawn]
    page = loop_report(
        run.plate, run.result.cycles, **limits, cycle_pictures=cycle_pictures, intro=intro,
        pictures=[("strain of the unfolding", (out / "strain.png").read_bytes()),
                  ("strokes of the first cycle's last step", (out / "strokes.png").read_bytes())],
    )
    report = out / "report.html"
    report.write_text(page)
    files.append(report)
    return files
