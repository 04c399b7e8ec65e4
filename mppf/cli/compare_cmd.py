"""``mppf compare``: deviation of a scanned plate from its design."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import click
import numpy as np

from mppf.cli._common import PICTURE_SUFFIXES, check_output_path, console, err_console, print_json, units_option
from mppf.core.defaults import RMS_TOLERANCE_MM, TOLERANCE_MM
from mppf.core.errors import InputError
from mppf.core.validate import check_number, check_positive
from mppf.measure.coverage import GAP_MM, GAP_SPACINGS, MAX_GAP_MM, check_gaps

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


def parse_mark(text: str | None):
    """``--mark X,Y,Z`` as a (3,) float array (mm, the scan's coordinates), or None."""
    if text is None:
        return None
    try:
        values = np.array([float(v) for v in text.split(",")], dtype=float)
    except ValueError:
        values = np.array([])
    if values.shape != (3,) or not np.all(np.isfinite(values)):
        raise InputError(f"--mark must be three numbers X,Y,Z (mm, scan coordinates), got {text!r}",
                         hint="e.g. --mark 1204.5,-311.0,87.2: where the reference-corner mark is in the scan")
    return values


MARK_REACH_MM = 500.0
"""How far outside the scan's bounding box a --mark may lie (a mark on the plate's very corner, a scan with holes)."""


def check_mark_on_scan(mark_mm, scan_points, scan_path, what: str = "--mark") -> None:
    """Refuse a reference mark far from every point of the scan (a typo, another unit, another scan's coordinates).

    Raises
    ------
    InputError
        The mark lies more than :data:`MARK_REACH_MM` outside the scan's bounding box.
    """
    lo, hi = scan_points.min(axis=0), scan_points.max(axis=0)
    outside = float(np.linalg.norm(np.maximum(0.0, np.maximum(lo - mark_mm, mark_mm - hi))))
    if outside > MARK_REACH_MM:
        span = ", ".join(f"{a:.0f}..{b:.0f}" for a, b in zip(lo, hi))
        raise InputError(f"{what} {','.join(f'{v:g}' for v in mark_mm)} lies {outside:.0f} mm outside the scan "
                         f"{scan_path} (its points span x, y, z {span} mm)",
                         hint="give where the reference-corner mark is in the scan's own coordinates (mm, or the "
                              "scan's units with --scan-units)")


@click.command("compare")
@click.argument("design", type=click.Path(dir_okay=False, path_type=str))
@click.argument("measured", type=click.Path(dir_okay=False, path_type=str))
@click.option("--tolerance", type=float, default=TOLERANCE_MM, show_default=True,
              help="Allowed absolute form deviation (mm).")
@click.option("--rms-tolerance", type=float, default=RMS_TOLERANCE_MM, show_default=True,
              help="Allowed RMS of the measured points' deviations (mm).")
@click.option("--job", "job_path", type=click.Path(dir_okay=False, path_type=str), default=None,
              help="The plate's job file: gives the trim margin, the thickness (the scan is the top skin), the "
                   "punch grid and press pose (punch deviations) and the reference corner of the mark.")
@click.option("--thickness", type=float, default=None, help="Plate thickness (mm), for --skin top/bottom.")
@click.option("--skin", type=click.Choice(["top", "mid", "bottom"]), default=None,
              help="Which skin the scan measured: the design is the mid-surface; top = its +normal side: the "
                   "design's concave side (the inside of the bowl), not whichever side faces up (with --job: the "
                   "side up on the press, where the planner lays the concave side), offset by half the "
                   "thickness. Default: top with --job, else mid.")
@click.option("--margin", type=float, default=None,
              help="Width of the trim margin (excess) the scanned plate still carries around the design outline "
                   "(mm); statistics cover the net plate only. Default: the job's, else 0.")
@click.option("--mark", "mark", default=None, metavar="X,Y,Z",
              help="Where the plate's reference-corner mark is in the scan (mm, scan coordinates); default: "
                   "<scan>.mark.json when present. It settles which way round a nearly symmetric plate lies.")
@click.option("--gap", "gap_mm", type=float, default=None, metavar="MM",
              help=f"Smallest allowed gap in the measurement (mm across): in tolerance needs the whole net plate "
                   f"measured without an empty gap wider than max(this, {GAP_SPACINGS:g} point spacings) "
                   f"[default: {GAP_MM:g}].")
@click.option("--max-gap", "max_gap_mm", type=float, default=None, metavar="MM",
              help=f"Largest allowed gap (mm across), however sparse the measurement [default: {MAX_GAP_MM:g}].")
@units_option
@click.option("--scan-units", type=click.Choice(["mm", "m"]), default=None,
              help="Length unit of the scan file when it differs from --units (scanners often write metres).")
@click.option("--json", "as_json", is_flag=True, help="Print the result as JSON.")
@click.option("--plot", type=click.Path(dir_okay=False, path_type=str), default=None,
              help="Save a colour deviation map (.png, .pdf, .svg).")
@click.option("--scale", "scale_mm", type=float, default=None,
              help="Half range of the colour scale of the pictures (mm); default 2 x the tolerance (fixed, the same "
                   "for every cycle of a plate).")
@click.option("--report", type=click.Path(dir_okay=False, path_type=str), default=None,
              help="Write an HTML report with the pictures and tables.")
@click.option("--export", "export_path", type=click.Path(dir_okay=False, path_type=str), default=None,
              help="Write every point (design coordinates) with its deviation, form deviation and flags: .ply "
                   "(CloudCompare scalar fields scalar_<name>) or .csv.")
def compare_command(design: str, measured: str, tolerance: float, rms_tolerance: float, job_path: str | None,
                    thickness: float | None, skin: str | None, margin: float | None, mark: str | None, units: str,
                    scan_units: str | None, as_json: bool, plot: str | None, scale_mm: float | None,
                    report: str | None, export_path: str | None, gap_mm: float | None = None,
                    max_gap_mm: float | None = None) -> None:
    """Compare the scan MEASURED with the design plate DESIGN.

    Registers the scan onto the design (ICP from the principal axes: point-to-point,
    then robust point-to-plane, pinned by the outline only where the surface leaves the pose
    free), measures the signed normal deviation of every scanned point (positive = on the
    design's +normal side) and decides by one rule: form max <= tolerance, RMS <= RMS
    tolerance, no point set aside as a scanner artefact beyond the tolerance and the whole
    net plate measured without a gap wider than the allowed gap (else "needs review",
    the areas not measured named and drawn). A scan far from its design whose outline and
    shape are the design's is this plate badly formed: out of tolerance. Only certain scanner artefacts of dense scans are set aside, and
    each is reported. With --job, the job's trim margin, thickness, punch grid and
    reference corner are used, as the loop does. Both files are point or mesh files (.csv
    .txt .xyz .ply .stl .obj). Exit code 2 for unreadable files or a scan that does not
    match the design; 4 when a nearly symmetric plate fits two ways round and no
    reference mark says which (both candidates shown).
    """
    from mppf.cli._common import read_input
    from mppf.measure.compare import compare
    from mppf.measure.options import CompareOptions

    # 1. options and output paths checked before the work
    mark_mm = _check_numbers(tolerance, rms_tolerance, scale_mm, mark, margin)
    gaps = check_gaps(GAP_MM if gap_mm is None else gap_mm, MAX_GAP_MM if max_gap_mm is None else max_gap_mm)
    _check_outputs(plot, report, export_path)
    # 2. the files: design, scan (its own units), job
    design_cloud = read_input(design, units=units)  # a plate smaller than 50 mm across: a unit mistake, refused
    measured_cloud = _read_scan(measured, scan_units or units)
    base = CompareOptions(tolerance_mm=tolerance, rms_tolerance_mm=rms_tolerance, design_faces=design_cloud.faces,
                          gap_mm=gaps[0], max_gap_mm=gaps[1])
    options = _options(job_path, design_cloud.points, measured, skin, thickness, margin, mark_mm, base)
    if options.reference_mark is not None:  # --mark, the mark file or the scan's header
        what = "--mark" if mark_mm is not None else "the reference mark of the scan (its mark file or header)"
        check_mark_on_scan(options.reference_mark[0], measured_cloud.points, measured, what)
    # 3. compare and decide
    result = compare(design_cloud.points, measured_cloud.points, options)
    # 4. pictures, report, export, the result
    _outputs(result, plot, report, export_path, scale_mm, (f"{design} (sha256 {design_cloud.sha256[:12]})",
                                                           f"{measured} (sha256 {measured_cloud.sha256[:12]})"))
    if as_json:
        doc = result.to_dict()
        doc.update({"design": design, "measured": measured, "design_sha256": design_cloud.sha256,
                    "measured_sha256": measured_cloud.sha256, "skin": skin or ("top" if job_path else "mid"),
                    "job": job_path})
        print_json(doc)
    else:
        _print_result(result, design, measured)
        for name, path in (("deviation map", plot), ("report", report), ("export", export_path)):
            if path:
                err_console.print(f"{name} written to {path}")
    if result.verdict is not None and result.verdict.exit_code:  # 5 out of tolerance, 6 needs review (README)
        raise click.exceptions.Exit(result.verdict.exit_code)


def _check_numbers(tolerance_mm, rms_tolerance_mm, scale_mm, mark, margin_mm):
    """Refuse tolerances (mm) and a --scale (mm) that are not positive, a malformed --mark and a --margin (mm)
    out of range, in that order; return the mark's point (:func:`parse_mark`, None without --mark)."""
    check_positive("--tolerance", tolerance_mm, unit="mm")
    check_positive("--rms-tolerance", rms_tolerance_mm, unit="mm")
    if scale_mm is not None:
        check_positive("--scale", scale_mm, unit="mm")
    mark_mm = parse_mark(mark)
    if margin_mm is not None:
        from mppf.planning.plan_steps import MAX_MARGIN_MM

        check_number("--margin", margin_mm, low=0.0, high=MAX_MARGIN_MM, unit="mm",
                     hint="the trim margin the scanned plate still carries, e.g. --margin 100 (0: trimmed)")
    return mark_mm


def _check_outputs(plot, report, export_path) -> None:
    """Refuse output paths that cannot be written (or of the wrong kind) before any work."""
    for path, what, suffixes, kind in ((plot, "the deviation map (--plot)", PICTURE_SUFFIXES, "picture"),
                                       (report, "the report (--report)", None, "file"),
                                       (export_path, "the export (--export)", (".ply", ".csv"), "point file")):
        if path:
            check_output_path(path, what, suffixes, kind=kind)


def _read_scan(measured: str, units: str):
    """The scan read in its units (``--scan-units``); refused with fewer points than a comparison needs."""
    from mppf.cli._common import read_input
    from mppf.measure.checks import MIN_POINTS

    measured_cloud = read_input(measured, units=units, units_option="--scan-units")
    if measured_cloud.n_points < MIN_POINTS:
        from mppf.core.errors import GeometryError

        raise GeometryError(f"the scan {measured} has {measured_cloud.n_points} point(s), a comparison needs at least "
                            f"{MIN_POINTS}", hint="check the scan export (the whole plate, not a selection)")
    return measured_cloud


def _options(job_path, design_points, scan_path, skin, thickness, margin, mark_mm, base):
    """The compare options: ``base`` with the job's (as the loop judges) and the explicit options (which win)."""
    if job_path is None:
        options = replace(base, offset_mm=skin_offset_mm(skin or "mid", thickness), margin_mm=0.0,
                          reference_mark=_mark_without_job(design_points, scan_path, mark_mm, margin))
    else:
        from mppf.measure.job_options import job_compare_options
        from mppf.planning.job import load_job

        job = load_job(job_path, require_seal=False)  # only read: an older unsealed job too, never a broken seal
        offset = None if skin is None else skin_offset_mm(skin, job.thickness_mm if thickness is None else thickness)
        options = job_compare_options(job, design_points, scan_path, offset_mm=offset, mark_mm=mark_mm, base=base)
    if margin is not None:
        options = replace(options, margin_mm=check_number("--margin", margin, low=0.0, unit="mm", hint=""))
    return options


def _mark_without_job(design_points, scan_path, mark_mm, margin=None):
    """The reference mark without a job: the design side at the corner of the plate as cut (--margin), own frame."""
    from mppf.measure.mark import reference_mark

    return reference_mark(scan_path, design_points, None, mark_mm, margin_mm=max(float(margin or 0.0), 0.0))


def _outputs(result, plot, report, export_path, scale_mm, names: tuple[str, str]) -> None:
    """Write the deviation map, the HTML report and the per-point export that were asked for (``names``: the
    design's and the scan's file, with their sha256, as the report names them)."""
    if plot:
        from mppf.report.deviation import plot_deviation

        _writing(plot, lambda: plot_deviation(result, plot, scale_mm=scale_mm))
    if report:
        from mppf.report.html import comparison_report

        page = comparison_report(result, design_name=names[0], measured_name=names[1], scale_mm=scale_mm)
        _writing(report, lambda: Path(report).write_text(page, encoding="utf-8"))
    if export_path:
        from mppf.report.export import export_points

        _writing(export_path, lambda: export_points(result, export_path))


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
    colour = {"in_tolerance": "green", "out_of_tolerance": "red", "needs_review": "yellow"}[c.verdict.kind]
    table.add_row("result", f"[{colour}]{c.verdict.label}[/]")
    table.add_row("decided by", "; ".join(c.verdict.reasons))
    table.add_row("form max |deviation| (decides)", f"{c.form_max_abs_mm:.3f} mm")
    table.add_row("RMS deviation (decides)", f"{c.rms_mm:.3f} mm")
    table.add_row("largest |deviation| of a point", f"{c.max_abs_mm:.3f} mm")
    table.add_row(f"within +-{c.tolerance_mm:g} mm (all net points)", f"{c.within_tolerance_pct:.1f} %")
    table.add_row("mean deviation", f"{c.mean_mm:+.3f} mm")
    table.add_row("inliers", f"{c.n_inliers} of {c.n_points} ({100.0 * c.n_inliers / c.n_points:.1f} %)")
    table.add_row("set aside / outside", f"{int(c.is_outlier.sum())} / {int(c.is_outside.sum())}")
    if c.set_aside is not None and c.set_aside.count:
        table.add_row("set aside (scanner artefacts)", c.set_aside.describe(c.tolerance_mm))
    if c.coverage is not None:
        cov = c.coverage
        table.add_row("not measured (decides)", "none: the whole net plate measured" if cov.complete else
                      f"{len(cov.regions)} area(s), {cov.uncovered_pct:.1f} % of the net plate: " + "; ".join(cov.names()))
        table.add_row("allowed gap / largest gap", f"{cov.allowed_gap_mm:.0f} mm / {cov.largest_gap_mm:.0f} mm")
    table.add_row("form smoothing", f"point spacing {c.form.get('spacing_mm', float('nan')):.1f} mm, noise "
                                    f"{c.form.get('noise_mm', float('nan')):.2f} mm (see the notes)")
    if c.margin_mm > 0:
        table.add_row(f"in the {c.margin_mm:g} mm trim margin", f"{int(c.in_margin.sum())} (not counted)")
    table.add_row("registration RMS", f"{reg.rms_mm:.3f} mm")
    table.add_row("registration iterations", f"{reg.iterations}" + ("" if reg.converged else " (not converged)"))
    table.add_row("registration judgement", reg.judgement or ("converged" if reg.converged else reg.stop_reason))
    start = reg.init.get("settled_by")
    if reg.ambiguous_start:
        table.add_row("warning", f"[yellow]nearly symmetric plate: two turns tie; settled by the {start}[/]")
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
