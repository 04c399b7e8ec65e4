"""``mppf compare``: deviation of a scanned plate from its design."""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np

from mppf.cli._common import PICTURE_SUFFIXES, check_output_path, console, err_console, print_json, units_option
from mppf.core.errors import InputError
from mppf.core.validate import check_number, check_positive

SKIN_SIDE = {"top": 1.0, "mid": 0.0, "bottom": -1.0}
"""Offset of the measured skin from the design mid-surface, in half thicknesses."""

HISTOGRAM_WIDTH = 40
"""Characters of the longest bar of the terminal histogram."""


def skin_offset_mm(skin: str, thickness_mm: float | None) -> float:
    """Normal offset of the measured skin from the design mid-surface (mm)."""
    if skin == "mid":
        return 0.0
    if thickness_mm is None:
        raise InputError(f"--skin {skin} needs the plate --thickness",
                         hint=f"e.g. --thickness 20 --skin {skin}")
    return SKIN_SIDE[skin] * 0.5 * check_positive("--thickness", thickness_mm, unit="mm")


@click.command("compare")
@click.argument("design", type=click.Path(dir_okay=False, path_type=str))
@click.argument("measured", type=click.Path(dir_okay=False, path_type=str))
@click.option("--tolerance", type=float, default=2.5, show_default=True,
              help="Allowed absolute deviation (mm).")
@click.option("--thickness", type=float, default=None, help="Plate thickness (mm), for --skin top/bottom.")
@click.option("--skin", type=click.Choice(["top", "mid", "bottom"]), default="mid", show_default=True,
              help="Which skin the scan measured: the design is the mid-surface; top = its +normal side "
                   "(the concave side of a curved plate), offset by half the thickness.")
@click.option("--margin", type=float, default=0.0, show_default=True,
              help="Width of the trim margin (excess) the scanned plate still carries around the design outline "
                   "(mm); statistics cover the net plate only.")
@units_option
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
@click.option("--plot", type=click.Path(dir_okay=False, path_type=str), default=None,
              help="Save a colour deviation map (.png, .pdf, .svg).")
@click.option("--report", type=click.Path(dir_okay=False, path_type=str), default=None,
              help="Write an HTML report with the pictures and tables.")
def compare_command(design: str, measured: str, tolerance: float, thickness: float | None, skin: str,
                    margin: float, units: str, as_json: bool, plot: str | None, report: str | None) -> None:
    """Compare the scan MEASURED with the design plate DESIGN.

    Registers the scan onto the design (ICP from the principal axes: point-to-point,
    then robust point-to-plane), measures the signed normal deviation of every scanned point (positive =
    on the design's +normal side) and prints the statistics: RMS, largest absolute
    deviation, percent within the tolerance, and a histogram. Outliers are flagged and
    left out. With --margin, the scan may still carry its trim margin (excess band) of that
    width around the design outline: it is measured but left out of the statistics.
    Both files are point or mesh files (.csv .txt .xyz .ply .stl .obj).
    Exit code 2 for unreadable files or a scan that does not match the design.
    """
    from mppf.geometry.read import read_points
    from mppf.measure.compare import compare

    check_positive("--tolerance", tolerance, unit="mm")
    check_number("--margin", margin, low=0.0, unit="mm", hint="")  # one line: the range says what to give
    offset = skin_offset_mm(skin, thickness)
    if plot:
        check_output_path(plot, "the deviation map (--plot)", PICTURE_SUFFIXES, kind="picture")
    if report:
        check_output_path(report, "the report (--report)")
    design_cloud = read_points(design, units=units)
    measured_cloud = read_points(measured, units=units)
    result = compare(design_cloud.points, measured_cloud.points, tolerance_mm=tolerance, offset_mm=offset,
                     design_faces=design_cloud.faces, margin_mm=margin)
    if plot:
        from mppf.report.deviation import plot_deviation

        _writing(plot, lambda: plot_deviation(result, plot))
    if report:
        from mppf.report.html import comparison_report

        page = comparison_report(
            result,
            design_name=f"{design} (sha256 {design_cloud.sha256[:12]})",
            measured_name=f"{measured} (sha256 {measured_cloud.sha256[:12]})",
        )
        _writing(report, lambda: Path(report).write_text(page, encoding="utf-8"))
    if as_json:
        doc = result.to_dict()
        doc.update({"design": design, "measured": measured, "design_sha256": design_cloud.sha256,
                    "measured_sha256": measured_cloud.sha256, "skin": skin})
        print_json(doc)
        return
    _print_result(result, design, measured)
    for name, path in (("deviation map", plot), ("report", report)):
        if path:
            err_console.print(f"{name} written to {path}")


def _writing(path: str, write) -> None:
    """Run ``write``; turn file-system errors into an InputError naming ``path``."""
    try:
        write()
    except OSError as exc:
        raise InputError(f"cannot write {path}: {exc.strerror or exc}",
                         hint="check that the folder exists and is writable") from None
    except ValueError as exc:  # matplotlib: unknown image format
        raise InputError(f"cannot write {path}: {exc}", hint="use a .png, .pdf or .svg file name") from None


def _print_result(result, design: str, measured: str) -> None:
    from rich.table import Table

    c = result
    reg = c.registration
    table = Table(title=f"{measured} against {design}", show_header=False, title_justify="left")
    table.add_column(style="bold")
    table.add_column(justify="right")
    verdict = "[green]IN tolerance[/]" if c.in_tolerance else "[red]OUT of tolerance[/]"
    table.add_row("result", verdict)
    table.add_row("RMS deviation", f"{c.rms_mm:.3f} mm")
    table.add_row("largest |deviation| (form)", f"{c.form_max_abs_mm:.3f} mm")
    table.add_row("largest |deviation| (points)", f"{c.max_abs_mm:.3f} mm")
    table.add_row(f"within +-{c.tolerance_mm:g} mm", f"{c.within_tolerance_pct:.1f} %")
    table.add_row("mean deviation", f"{c.mean_mm:+.3f} mm")
    table.add_row("inliers", f"{c.n_inliers} of {c.n_points} ({100.0 * c.n_inliers / c.n_points:.1f} %)")
    table.add_row("outliers / outside", f"{int(c.is_outlier.sum())} / {int(c.is_outside.sum())}")
    if c.margin_mm > 0:
        table.add_row(f"in the {c.margin_mm:g} mm trim margin", f"{int(c.in_margin.sum())} (not counted)")
    table.add_row("registration RMS", f"{reg.rms_mm:.3f} mm")
    table.add_row("registration iterations", f"{reg.iterations}" + ("" if reg.converged else " (not converged)"))
    if reg.ambiguous_start:
        table.add_row("warning", "[yellow]symmetric plate: check the turn of the registration[/]")
    console.print(table)
    console.print(ascii_histogram(c.histogram_edges_mm, c.histogram_counts, c.tolerance_mm), highlight=False,
                  markup=False)


def ascii_histogram(edges, counts, tolerance_mm: float, width: int = HISTOGRAM_WIDTH) -> str:
    """A text histogram, one line per bin: range, bar of '#', count; bins outside the tolerance marked '!'."""
    edges = np.asarray(edges, dtype=float)
    counts = np.asarray(counts, dtype=int)
    top = max(int(counts.max()) if counts.size else 0, 1)
    lines = ["deviation histogram (mm)"]
    for lo, hi, n in zip(edges[:-1], edges[1:], counts):
        bar = "#" * int(round(width * n / top))
        if n and not bar:
            bar = "."
        flag = "!" if max(abs(lo), abs(hi)) > tolerance_mm + 1e-9 and n else " "
        lines.append(f"{flag} {lo:+8.2f} .. {hi:+8.2f} | {bar:<{width}} {n}")
    return "\n".join(lines)


COMMANDS = [compare_command]
