"""``mppf plan``: strokes of both punch matrices from a design and its flat plate."""

from __future__ import annotations

import hashlib
from pathlib import Path

import click

from mppf.cli._common import (PICTURE_SUFFIXES, RichReporter, check_design_size, check_output_path, console, esc,
                              print_json, read_input, scale_option, units_option)
from mppf.core.errors import InputError
from mppf.forming.material import DEFAULT_YIELD_UNCERTAINTY_PCT, check_yield_uncertainty
from mppf.model.material import MATERIALS, Material
from mppf.model.plan_options import PlanOptions


THICKNESS_MAX_MM = 200.0
"""Thickest plate planned (mm): beyond, the value is a typing error or in another unit."""


def _material(name, youngs, poisson, yield_mpa) -> Material | None:
    from mppf.core.validate import check_number, check_positive

    if name is None and youngs is None and poisson is None and yield_mpa is None:
        return None
    for option, value in (("--youngs", youngs), ("--yield", yield_mpa)):
        if value is not None:
            check_positive(option, value, unit="MPa", hint=f"give {option} in MPa, e.g. 206000 (Young's modulus "
                                                          "of steel) or 235 (its yield stress)")
    if poisson is not None:
        check_number("--poisson", poisson, low=0.0, high=0.5, high_open=True, hint="give e.g. 0.3 (steel)")
    base = MATERIALS[name or "steel"]
    return Material(
        youngs_modulus_mpa=base.youngs_modulus_mpa if youngs is None else youngs,
        poisson=base.poisson if poisson is None else poisson,
        yield_stress_mpa=base.yield_stress_mpa if yield_mpa is None else yield_mpa,
    )


def _yield_uncertainty(pct, springback: bool) -> float:
    """The declared yield scatter (%) the first press is planned for: the default with --springback, checked."""
    if pct is None:
        return DEFAULT_YIELD_UNCERTAINTY_PCT if springback else 0.0
    check_yield_uncertainty(pct)
    if not springback:
        raise InputError(f"--yield-uncertainty {pct:g} % has no effect without --springback (it sets the yield stress "
                         "the springback is compensated for)", hint="add --springback --material steel|ah36, or leave "
                         "--yield-uncertainty out")
    return float(pct)


def _check_plan_options(thickness_mm, transition_mm, output, plot) -> None:
    """Refuse a thickness over :data:`THICKNESS_MAX_MM` (mm), a transition width (mm) that is not positive,
    and output paths that cannot be written, before any file is read."""
    if thickness_mm > THICKNESS_MAX_MM:  # 0, negative and NaN: the planner's own message
        raise InputError(f"--thickness {thickness_mm:g} mm is not a plate thickness (at most {THICKNESS_MAX_MM:g} mm)",
                         hint="give the plate thickness in mm, e.g. 20")
    if transition_mm is not None:
        from mppf.core.validate import check_positive

        check_positive("--transition", transition_mm, unit="mm", hint="give the shared width in mm, e.g. 300")
    if output:
        check_output_path(output, "the job file")
    if plot:
        check_output_path(plot, "the stroke map", PICTURE_SUFFIXES, kind="picture")


def _inputs_record(design_cloud, flat_cloud, press_file: Path, units: str) -> dict:
    """The files planned from as the job records them: path and SHA-256 of design, flat and press, and the units."""
    return {
        "design": {"path": str(design_cloud.path), "sha256": design_cloud.sha256},
        "flat": {"path": str(flat_cloud.path), "sha256": flat_cloud.sha256},
        "press": {"path": str(press_file), "sha256": hashlib.sha256(press_file.read_bytes()).hexdigest()},
        "units": units,
    }


def _fmt(value, digits=1):
    return "-" if value is None else f"{value:.{digits}f}"


def _print_summary(summary: dict, output) -> None:
    from rich.table import Table

    reg, pose = summary["registration"], summary["pose"]
    table = Table(title=f"plan: {esc(summary['press'])} ({summary['matrix'][0]} x {summary['matrix'][1]}), "
                        f"plate {summary['thickness_mm']:g} mm")
    table.add_column("item")
    table.add_column("value", justify="right")
    table.add_row("registration", f"{reg['method']}, RMS {_fmt(reg['rms_mm'], 2)} mm, "
                                  f"turn {_fmt(reg['rotation_deg'])} deg")
    if reg.get("neighbour_strain_p95_pct") is not None:
        table.add_row("flat vs design strain (p95)", f"{reg['neighbour_strain_p95_pct']:.3f} %")
    table.add_row("flat plate (net)", f"{summary['plate_size_mm'][0]:.0f} x {summary['plate_size_mm'][1]:.0f} mm")
    if summary["margin_mm"] > 0:
        table.add_row("trim margin (cut, then trim after forming)", f"{summary['margin_mm']:g} mm all round")
    table.add_row("tilt x / y", f"{pose['tilt_x_deg']:.3f} / {pose['tilt_y_deg']:.3f} deg")
    table.add_row("vertical offset", f"{pose['offset_mm']:.1f} mm")
    table.add_row("largest punch travel", f"{summary['max_travel_mm']:.1f} mm")
    table.add_row("steps", str(summary["n_steps"]))
    table.add_row("largest neighbour change / step",
                  f"{summary['max_neighbour_step_mm']:.1f} mm")
    table.add_row("smallest tip gap", f"{_fmt(summary['min_gap_mm'], 2)} mm")
    if summary["springback"].get("enabled"):
        _add_springback_rows(table, summary["springback"])
    console.print(table)
    _print_strokes_and_corners(summary)
    if summary.get("sections"):
        _print_sections(summary["sections"])
    for warning in summary.get("warnings", []):
        console.print(f"warning: {warning}", style="yellow", markup=False, soft_wrap=True)
    if output:
        console.print(f"job written to {output}", markup=False, soft_wrap=True)


def _add_springback_rows(table, springback: dict) -> None:
    """The springback rows of the plan table: the radii (m), the planned yield stress, the virtual cycles."""
    for what in ("target", "loaded"):
        if springback.get(f"{what}_radii_mm") is None:  # the arcs did not fit: refined from the design
            continue
        text = ", ".join(_fmt(r and r / 1000, 2) + " m" for r in springback[f"{what}_radii_mm"])
        table.add_row(f"springback: {what} radii", text)
    first = springback.get("first_press")
    if first:
        table.add_row("springback: planned yield stress", f"{first['planned_yield_mpa']:.0f} MPa (nominal "
                      f"{first['nominal_yield_mpa']:.0f} - {first['yield_uncertainty_pct']:g} %: under-bent)")
    refinement = springback.get("refinement")
    if refinement:
        table.add_row("springback: virtual cycles", f"{refinement['virtual_cycles']}, predicted largest "
                      f"deviation {refinement['history_mm'][0]:.1f} -> {refinement['predicted_max_mm']:.2f} mm")


def _print_strokes_and_corners(summary: dict) -> None:
    """The final strokes of both matrices (mm) and the plate corners on the bed (mm), as two tables."""
    from rich.table import Table

    strokes = Table(title="final strokes (tip heights, mm)")
    for col in ("matrix", "active", "parked", "min", "max", "limits", "largest travel"):
        strokes.add_column(col, justify="right")
    for name in ("upper", "lower"):
        m = summary[name]
        strokes.add_row(name, str(m["active"]), f"{m['parked']} at {m['park_mm']:g}", f"{m['min_mm']:.1f}",
                        f"{m['max_mm']:.1f}", f"{m['limits_mm'][0]:g} .. {m['limits_mm'][1]:g}",
                        f"{m['max_travel_mm']:.1f}")
    console.print(strokes)

    corners = Table(title="net plate corners on the bed" if summary["margin_mm"] > 0 else "plate corners on the bed")
    for col in ("corner", "x (mm)", "y (mm)"):
        corners.add_column(col, justify="right")
    for name, (x, y, _) in zip(("-x -y", "+x -y", "+x +y", "-x +y"), summary["plate_corners_mm"]):
        corners.add_row(name, f"{x:.1f}", f"{y:.1f}")
    console.print(corners)


def _print_sections(sections: list[dict]) -> None:
    from rich.table import Table

    table = Table(title=f"the plate is pressed in {len(sections)} sections (placement of each: mppf press shows it)")
    for col in ("section", "plate centre on the bed x / y (mm)", "steps", "largest travel (mm)",
                "border step (mm)"):
        table.add_column(col, justify="right")
    for s in sections:
        x, y = (float(c) + 0.0 for c in s["plate_centre_mm"][:2])  # + 0.0: no "-0"
        table.add_row(str(s["index"]), f"{x:.0f} / {y:.0f}", str(s["n_steps"]), _fmt(s["max_travel_mm"]),
                      _fmt(s["border_step_mm"], 2))
    console.print(table)


@click.command("plan")
@click.argument("design", type=click.Path(dir_okay=False, path_type=str))
@click.argument("flat", type=click.Path(dir_okay=False, path_type=str))
@click.option("--press", "press_path", type=click.Path(dir_okay=False, path_type=str), default=None,
              help="Press description (TOML). Default: the bundled example press.")
@click.option("--thickness", "thickness_mm", type=float, required=True, help="Plate thickness in mm.")
@click.option("--steps", type=click.IntRange(min=1), default=None,
              help="Number of press steps (default: the fewest within the dimpling limit).")
@click.option("--springback", is_flag=True, help="Over-bend to pre-compensate springback (needs a material).")
@click.option("--yield-uncertainty", "yield_uncertainty", type=float, default=None,
              help=f"With --springback: scatter of the plate's yield stress (+- %, the mill certificate's; default "
                   f"{DEFAULT_YIELD_UNCERTAINTY_PCT:g}). Springback is compensated for the weakest plate of the "
                   "range, so the first press under-bends and never over-bends (0: the nominal yield stress).")
@click.option("--margin", "margin_mm", type=float, default=None,
              help="Trim margin (mm): the flat plate is cut this much larger all round, pressed with the "
                   "punches under the margin, and trimmed after forming; default the press's [forming] margin_mm.")
@click.option("--material", type=click.Choice(sorted(MATERIALS)), default=None,
              help="Material preset: steel (E 206 GPa, nu 0.3, yield 235 MPa) or ah36 (yield 355 MPa).")
@click.option("--youngs", type=float, default=None, help="Young's modulus in MPa (overrides the preset).")
@click.option("--poisson", type=float, default=None, help="Poisson's ratio (overrides the preset).")
@click.option("--yield", "yield_mpa", type=float, default=None, help="Yield stress in MPa (overrides the preset).")
@click.option("--transition", "transition_mm", type=float, default=None,
              help="A plate larger than the bed is planned in sections: the least width in mm that neighbouring "
                   "sections share and blend over (default: 3 punch pitches; docs/sections.md).")
@units_option
@scale_option
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=str), default=None,
              help="Write the job file (JSON) here.")
@click.option("--plot", type=click.Path(dir_okay=False, path_type=str), default=None,
              help="Draw the stroke map of the last step (.png .pdf .svg).")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as JSON.")
def plan_command(design, flat, press_path, thickness_mm, steps, springback, margin_mm, material, youngs, poisson,
                 yield_mpa, transition_mm, units, scale, output, plot, as_json, yield_uncertainty):
    """Plan the strokes of both punch matrices to press FLAT into DESIGN.

    DESIGN is the curved plate (mid-surface points or mesh), FLAT its unfolded plate
    (e.g. from 'mppf unfold'; same point order = paired registration). --scale applies to
    DESIGN (a model-scale CAD file); FLAT, written by mppf, is at full scale. Nothing is
    written when the plan fails validation. A plate larger than the bed is planned in sections
    (the plate shifted on the bed between them; see docs/sections.md).
    """
    from mppf.planning.job import save_job
    from mppf.planning.plan import plan_summary  # numpy/scipy work: imported when planning
    from mppf.planning.sectional import plan_plate
    from mppf.planning.sectional_marks import sections_summary
    from mppf.model.press import example_press_path, load_press

    _check_plan_options(thickness_mm, transition_mm, output, plot)
    press_file = Path(press_path) if press_path else example_press_path()
    press = load_press(press_file)
    mat = _material(material, youngs, poisson, yield_mpa)
    if springback and mat is None:
        raise InputError("--springback needs the plate material",
                         hint="add --material steel|ah36 or --youngs/--poisson/--yield")
    uncertainty_pct = _yield_uncertainty(yield_uncertainty, springback)
    design_cloud = read_input(design, units=units, scale=scale)
    flat_cloud = read_input(flat, units=units)
    for path, cloud in ((design, design_cloud), (flat, flat_cloud)):
        check_design_size(path, cloud.n_points)
    inputs = _inputs_record(design_cloud, flat_cloud, press_file, units)
    reporter = RichReporter(enabled=not as_json)
    options = PlanOptions(steps=steps, material=mat, springback=springback, yield_uncertainty_pct=uncertainty_pct,
                          margin_mm=margin_mm, transition_mm=transition_mm)
    job = plan_plate(design_cloud.points, flat_cloud.points, press, thickness_mm, options,
                     design_faces=design_cloud.faces, reporter=reporter, inputs=inputs)
    reporter.finish()
    if plot:  # the picture first: a job file exists only when the whole command succeeded
        from mppf.report.strokes import plot_strokes

        plot_strokes(job, plot)
    if output:
        save_job(job, output)
    summary = plan_summary(job)
    if job.sections:
        summary["sections"] = sections_summary(job)
        summary["warnings"] = list(job.sectional.warnings or ()) if job.sectional is not None else []
    if output:
        summary["job"] = {"path": output, "sha256": job.sha256()}
    if as_json:
        print_json(summary)
    else:
        _print_summary(summary, output)


COMMANDS = [plan_command]
