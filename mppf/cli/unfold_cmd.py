"""``mppf unfold``: flatten a curved design plate and report the strain it costs."""

from __future__ import annotations

from pathlib import Path

import click

from mppf.cli._common import PICTURE_SUFFIXES, check_output_path, console, print_json, units_option
from mppf.geometry.unfold_report import STRAIN_LIMIT_PCT


@click.command("unfold")
@click.argument("design", type=click.Path(dir_okay=False, path_type=str))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=str),
              help="Flat file to write (.csv .txt .xyz .ply): same point order and count as DESIGN.")
@units_option
@click.option("--strain-limit", "strain_limit_pct", type=float, default=STRAIN_LIMIT_PCT, show_default=True,
              help="In-plane strain (percent) above which the plate gets a warning.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False, path_type=str), default=None,
              help="Write a strain picture of the flat plate (.png .pdf .svg).")
def unfold_command(design: str, output: str, units: str, strain_limit_pct: float, as_json: bool,
                   plot_path: str | None) -> None:
    """Unfold the curved plate in DESIGN into its flat shape and write it to OUTPUT.

    DESIGN is a point or mesh file (.csv .txt .xyz .ply .stl .obj) in any coordinates.
    The flat plate lies at z = 0, centred at the origin, its longer side along x, seen
    from the design's +n side (never mirrored). Point k of the flat file is point k of
    DESIGN, so the pair serves as known correspondences ('mppf register --method
    paired', the planner). Prints the in-plane strain (RMS, max), the area and outline
    length changes and a warning when the strain exceeds --strain-limit.
    """
    from mppf.geometry.read import read_points
    from mppf.geometry.unfold import unfold
    from mppf.geometry.write import write_points

    out = _writable(output, plot_path)
    cloud = read_points(design, units=units)
    result = unfold(cloud.points, cloud.faces, strain_limit_pct=strain_limit_pct)
    header = (f"x_mm,y_mm,z_mm  flat (unfolded) shape of {Path(design).name}; point k = design point k; "
              f"strain RMS {result.rms_strain_pct:.4f} %, max {result.max_strain_pct:.4f} %")
    if plot_path is not None:  # the picture first: the flat file exists only when everything succeeded
        from mppf.report.strain import plot_strain

        plot_strain(result, plot_path)
    write_points(out, result.flat, header=header,
                 faces=result.faces if out.suffix.lower() == ".ply" else None)
    report = {
        **result.to_dict(),
        "design": str(design),
        "design_sha256": cloud.sha256,
        "output": str(out),
        "plot": plot_path,
        "tf_flat_design": result.tf_flat_design.tolist(),
        "worst_flat_xy_mm": result.flat[result.worst_point, :2].tolist(),
        "strain_pct": result.strain_pct.round(5).tolist(),
    }
    if as_json:
        print_json(report)
        return
    _print_report(report)


def _writable(output: str, plot_path: str | None) -> Path:
    """Refuse output paths that cannot be written, before the work is done."""
    from mppf.geometry.write import WRITE_SUFFIXES

    path = check_output_path(output, "the flat file", WRITE_SUFFIXES, kind="point file")
    if plot_path is not None:
        check_output_path(plot_path, "the strain picture", PICTURE_SUFFIXES, kind="picture")
    return path


def _print_report(report: dict) -> None:
    from rich.table import Table

    table = Table(title=f"unfolding of {report['design']}", show_header=False, title_justify="left")
    table.add_column(style="bold")
    table.add_column()
    width, height = report["flat_size_mm"]
    table.add_row("points", f"{report['n_points']} ({report['n_triangles']} triangles)")
    table.add_row("flat plate", f"{width:.1f} x {height:.1f} mm")
    table.add_row("strain RMS", f"{report['rms_strain_pct']:.4f} %")
    over = report["max_strain_pct"] > report["strain_limit_pct"]
    style = "bold red" if over else "green"
    table.add_row("strain max", f"[{style}]{report['max_strain_pct']:.4f} %[/] near {report['worst_region']} "
                                f"(point {report['worst_point']}; limit {report['strain_limit_pct']:g} %)")
    table.add_row("area change", f"{report['area_change_pct']:+.4f} %")
    table.add_row("outline length change", f"{report['outline_length_change_pct']:+.4f} %")
    table.add_row("developable", "yes (max strain below 0.1 %)" if report["developable"] else "no")
    table.add_row("flat file", report["output"])
    if report["plot"]:
        table.add_row("strain picture", report["plot"])
    console.print(table)
    for warning in report["warnings"]:
        console.print(f"[bold yellow]warning:[/] {warning}")


COMMANDS = [unfold_command]
