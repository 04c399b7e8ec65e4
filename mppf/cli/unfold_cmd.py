"""``mppf unfold``: flatten a curved design plate, report the strain it costs, write the flat.

The flat goes to point files (the planner's input) and to a DXF drawing for the NC cutter
(:mod:`mppf.geometry.dxf`): ``-o flat.csv -o flat.dxf`` writes both.
"""

from __future__ import annotations

from pathlib import Path

import click

from mppf.cli._common import (PICTURE_SUFFIXES, RichReporter, check_design_size, check_output_path, console, esc,
                              print_json, read_input, scale_option, units_option)
from mppf.geometry.unfold_report import STRAIN_LIMIT_PCT

DXF_SUFFIX = ".dxf"


@click.command("unfold")
@click.argument("design", type=click.Path(dir_okay=False, path_type=str))
@click.option("-o", "--output", "outputs", required=True, multiple=True, type=click.Path(dir_okay=False, path_type=str),
              help="Flat file to write (.csv .txt .xyz .ply: same point order and count as DESIGN; .dxf: the "
                   "drawing for the cutter). Give -o more than once to write several.")
@units_option
@scale_option
@click.option("--margin", "margin_mm", type=click.FloatRange(min=0.0), default=None,
              help="DXF only: trim margin (mm) the cut outline is grown by; default the bundled example "
                   "press's [forming] margin_mm (100 mm); 0 cuts the plate to its net outline.")
@click.option("--job", "job_path", type=click.Path(dir_okay=False, path_type=str), default=None,
              help="DXF only: a job planned for this design (mppf plan -o JOB.json): mark its punch centres, "
                   "take its margin (unless --margin) and the reference corner as it lies on that press.")
@click.option("--strain-limit", "strain_limit_pct", type=float, default=STRAIN_LIMIT_PCT, show_default=True,
              help="In-plane strain (percent) above which the plate gets a warning.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as JSON.")
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False, path_type=str), default=None,
              help="Write a strain picture of the flat plate (.png .pdf .svg).")
def unfold_command(design: str, outputs: tuple[str, ...], units: str, scale: float, margin_mm: float | None,
                   job_path: str | None, strain_limit_pct: float, as_json: bool, plot_path: str | None) -> None:
    """Unfold the curved plate in DESIGN into its flat shape and write it to OUTPUT.

    DESIGN is a point, mesh, CAD or scan file (.csv .txt .xyz .ply .stl .obj .igs .stp
    .e57 .las .laz) in any coordinates. The flat plate lies at z = 0, centred at the
    origin, its longer side along x, seen from the design's +n side (never mirrored).
    Point k of the flat file is point k of DESIGN, so the pair serves as known
    correspondences ('mppf register --method paired', the planner). A .dxf output is the
    cutter's drawing: cut outline (net grown by --margin), net outline, reference mark
    (layers CUT, NET, MARK, TEXT, PUNCH; docs/file-formats.md). Prints the in-plane strain
    (RMS, max), the area and outline length changes and a warning when the strain exceeds
    --strain-limit.
    """
    from mppf.geometry.unfold import unfold

    from mppf.core.validate import check_number, check_positive

    check_positive("--strain-limit", strain_limit_pct, unit="%", hint="give the warning limit in percent, e.g. 1.5")
    if margin_mm is not None:
        check_number("--margin", margin_mm, low=0.0, unit="mm", hint="give e.g. --margin 100 (0: the net outline)")
    paths = _writable(outputs, plot_path)
    job = _job(job_path) if job_path else None
    cloud = read_input(design, units=units, scale=scale)
    check_design_size(design, cloud.n_points)
    reporter = RichReporter(enabled=not as_json)
    reporter.info(f"unfolding {cloud.n_points} points of {design}")
    result = unfold(cloud.points, cloud.faces, strain_limit_pct=strain_limit_pct)
    reporter.close()
    drawing = _drawing(result, design, cloud, margin_mm, job) if any(_is_dxf(p) for p in paths) else None
    if plot_path is not None:  # the picture first: the flat files exist only when everything succeeded
        from mppf.report.strain import plot_strain

        plot_strain(result, plot_path)
    for out in paths:
        _write_flat(out, result, design, drawing)
    report = {
        **result.to_dict(),
        "design": str(design),
        "design_sha256": cloud.sha256,
        "output": str(paths[0]),
        "outputs": [str(p) for p in paths],
        "plot": plot_path,
        "tf_flat_design": result.tf_flat_design.tolist(),
        "worst_flat_xy_mm": result.flat[result.worst_point, :2].tolist(),
        "strain_pct": result.strain_pct.round(5).tolist(),
    }
    if drawing is not None:
        report["dxf"] = _drawing_report(drawing)
    if as_json:
        print_json(report)
        return
    _print_report(report)


def _writable(outputs: tuple[str, ...], plot_path: str | None) -> list[Path]:
    """Refuse output paths that cannot be written, before the work is done."""
    from mppf.geometry.write import WRITE_SUFFIXES

    paths = [check_output_path(output, "the flat file", WRITE_SUFFIXES + (DXF_SUFFIX,), kind="point file")
             for output in outputs]
    if plot_path is not None:
        check_output_path(plot_path, "the strain picture", PICTURE_SUFFIXES, kind="picture")
    return paths


def _is_dxf(path: Path) -> bool:
    return path.suffix.lower() == DXF_SUFFIX


def _write_flat(out: Path, result, design: str, drawing) -> None:
    from mppf.geometry.write import write_points

    if _is_dxf(out):
        from mppf.geometry.dxf import write_flat_dxf

        write_flat_dxf(out, drawing)
        return
    header = (f"x_mm,y_mm,z_mm  flat (unfolded) shape of {Path(design).name}; point k = design point k; "
              f"strain RMS {result.rms_strain_pct:.4f} %, max {result.max_strain_pct:.4f} %")
    write_points(out, result.flat, header=header, faces=result.faces if out.suffix.lower() == ".ply" else None)


def _job(job_path: str):
    """The job file, through the one job validator (a job the press would refuse marks no punches)."""
    from mppf.core.errors import ConfigError, LimitError
    from mppf.planning.job import load_job
    from mppf.planning.validate import validate_job

    job = load_job(job_path)
    try:
        validate_job(job)
    except (ConfigError, LimitError) as exc:
        raise type(exc)(f"job {job_path}: {exc.message}", hint=exc.hint) from None
    return job


def _drawing(result, design: str, cloud, margin_mm: float | None, job):
    """The cutter's drawing: margin from --margin, else the job's, else the example press's."""
    from mppf.geometry.dxf import flat_drawing, section_marks_of

    tf_press_flat, punches, marks = None, None, []
    if job is not None:
        tf_press_flat, punches = _job_placement(job, result, cloud)
        marks = section_marks_of(job)
        if margin_mm is None and job.layout is not None:
            margin_mm = job.layout.margin_mm
    if margin_mm is None:
        from mppf.model.press import example_press_path, load_press

        margin_mm = load_press(example_press_path()).margin_mm
    width, height = result.to_dict()["flat_size_mm"]
    label = f"{Path(design).stem}  {width:.0f} x {height:.0f} mm net, margin {margin_mm:g} mm"
    return flat_drawing(result.flat[:, :2], result.faces, margin_mm, tf_press_flat=tf_press_flat,
                        punches_press_mm=punches, label=label, section_marks=marks)


def _job_placement(job, result, cloud):
    """How the job lays this flat on its press, and its active punch axes; refuse a job of another plate."""
    import numpy as np

    from mppf.core.errors import InputError
    from mppf.core.transform import apply_tf

    planned = job.reports.design_sha256
    if planned and planned != cloud.sha256:
        raise InputError("the job was planned for another design (its design SHA-256 differs from this file's)",
                         hint="give the job planned from this design file, or leave out --job")
    lying = apply_tf(job.tf_press_flat, result.flat)[:, 2] - job.thickness_mm / 2.0
    if np.abs(lying).max() > 1.0:
        raise InputError(f"the job lays another flat on the press (this flat lies up to {np.abs(lying).max():.1f} mm "
                         "off the bed in it)", hint="unfold the design the job was planned from with this mppf")
    active = job.steps[-1].active
    x, y = np.meshgrid(job.punch_x_mm, job.punch_y_mm)
    return job.tf_press_flat, np.column_stack([x[active], y[active]])


def _drawing_report(drawing) -> dict:
    from mppf.core.polygon import area, perimeter

    return {"cut_area_mm2": area(drawing.cut_mm), "cut_perimeter_mm": perimeter(drawing.cut_mm),
            "net_area_mm2": area(drawing.net_mm[0]), "net_perimeter_mm": perimeter(drawing.net_mm[0]),
            "margin_mm": drawing.margin_mm, "reference_corner_mm": drawing.mark_mm.tolist(),
            "n_punches": int(drawing.punches_mm.shape[0]), "n_section_marks": len(drawing.section_marks)}


def _print_report(report: dict) -> None:
    from rich.table import Table

    table = Table(title=f"unfolding of {esc(report['design'])}", show_header=False, title_justify="left")
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
    table.add_row("flat file" if len(report["outputs"]) == 1 else "flat files", esc(", ".join(report["outputs"])))
    if "dxf" in report:
        dxf = report["dxf"]
        x, y = dxf["reference_corner_mm"]
        punches = f", {dxf['n_punches']} punch centres" if dxf["n_punches"] else ""
        table.add_row("cutter drawing", f"cut outline {dxf['cut_area_mm2'] / 1e6:.3f} m2 "
                                        f"(margin {dxf['margin_mm']:g} mm), reference mark at x {x:.0f}, "
                                        f"y {y:.0f} mm{punches}")
    if report["plot"]:
        table.add_row("strain picture", esc(report["plot"]))
    console.print(table)
    for warning in report["warnings"]:
        console.print(f"[bold yellow]warning:[/] {esc(warning)}", soft_wrap=True)


COMMANDS = [unfold_command]
