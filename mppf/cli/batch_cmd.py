"""``mppf batch``: unfold and plan many plates at once (a hull block), resumably, on every core."""

from __future__ import annotations

import os
from pathlib import Path

import click

from mppf.cli._common import units_option
from mppf.core.errors import InputError


@click.command("batch")
@click.argument("designs", nargs=-1, type=click.Path(dir_okay=False, path_type=str))
@click.option("--manifest", type=click.Path(dir_okay=False, path_type=str), default=None,
              help="CSV of the plates: name, design, flat, thickness_mm, material, springback (paths relative to it).")
@click.option("-o", "--output", "out_dir", type=click.Path(file_okay=False, path_type=str), required=True,
              help="Folder for the jobs, the unfolded flats and summary.csv / summary.html (made if missing).")
@click.option("--press", "press_path", type=click.Path(dir_okay=False, path_type=str), default=None,
              help="Press description (TOML). Default: the bundled example press.")
@click.option("--thickness", "thickness_mm", type=float, default=None,
              help="Plate thickness in mm for design files (and manifest rows without thickness_mm).")
@click.option("--material", type=click.Choice(["steel", "ah36"]), default=None,
              help="Material of design files (and manifest rows without one).")
@click.option("--springback", is_flag=True, help="Design files: pre-compensate springback (needs --material).")
@click.option("--margin", "margin_mm", type=float, default=None, help="Trim margin in mm (default: the press's).")
@click.option("--transition", "transition_mm", type=float, default=None,
              help="Least width in mm that neighbouring sections share (default: 3 punch pitches).")
@click.option("-j", "--jobs", "workers", type=int, default=None,
              help="Worker processes (default: every core this process may run on).")
@units_option
def batch_command(designs, manifest, out_dir, press_path, thickness_mm, material, springback, margin_mm,
                  transition_mm, workers, units):
    """Unfold and plan many plates: DESIGN files, or --manifest PLATES.csv.

    Each plate is unfolded (unless the manifest gives its flat), planned in one piece or, when it
    is larger than the bed, in sections, and written as OUT/<name>.job.json. A plate whose finished
    job holds the same input hashes (files, press, options) is skipped, so running the same command
    again resumes an interrupted batch. A bad plate does not stop the batch: it is listed with its
    reason in OUT/summary.csv and OUT/summary.html. Exit code 2 when the input is bad or any plate
    failed, 0 when every plate was planned or skipped.
    """
    from mppf.cli._common import RichReporter, console
    from mppf.core.threads import cores
    from mppf.core.validate import check_number
    from mppf.planning.batch import BatchOptions, plates_from_files, read_manifest, run_batch
    from mppf.planning.batch_summary import totals, write_csv, write_html
    from mppf.model.press import example_press_path, load_press

    if bool(designs) == bool(manifest):
        raise InputError("give either design files or --manifest, not both" if designs else "no plates given",
                         hint="mppf batch PLATE.csv ... --thickness 20 -o OUT, "
                              "or mppf batch --manifest PLATES.csv -o OUT")
    if springback and material is None and not manifest:
        raise InputError("--springback needs the plate material", hint="add --material steel|ah36")
    for name, value in (("--thickness", thickness_mm), ("--margin", margin_mm), ("--transition", transition_mm)):
        if value is not None:
            check_number(name, value, low=0.0, low_open=name == "--thickness", unit="mm")
    n_workers = cores() if workers is None else check_number("--jobs", workers, low=1, high=256, integer=True)
    press_file = str(Path(press_path) if press_path else example_press_path())
    press = load_press(press_file)  # a bad press description is bad input for the whole batch, before any work
    if thickness_mm is not None:
        check_number("--thickness", thickness_mm, low=0.0, low_open=True, high=press.max_thickness_mm, unit="mm",
                     hint=f"the press takes plates up to {press.max_thickness_mm:g} mm ([forming] max_thickness_mm)")
    plates = (read_manifest(manifest, thickness_mm, material, max_thickness_mm=press.max_thickness_mm) if manifest
              else plates_from_files(designs, thickness_mm, material, springback))
    _check_out_dir(out_dir)
    options = BatchOptions(press_path=press_file, out_dir=out_dir, units=units, margin_mm=margin_mm,
                           transition_mm=transition_mm, workers=int(n_workers))
    reporter = RichReporter()
    reporter.info(f"{len(plates)} plate(s), {options.workers} worker(s), jobs in {out_dir}")
    rows = run_batch(plates, options, reporter=reporter)
    csv_path = write_csv(rows, Path(out_dir) / "summary.csv")
    write_html(rows, Path(out_dir) / "summary.html", title=f"mppf batch: {len(rows)} plates")
    t = totals(rows)
    console.print(f"{t['plates']} plate(s): {t['planned']} planned, {t['skipped']} skipped (unchanged), "
                  f"{t['failed']} failed; {t['sections']} section(s), {t['steps']} step(s); summary {csv_path}")
    failed = [r for r in rows if r["status"] == "failed"]
    if failed:
        listed = "; ".join(f"{r['plate']}: {r['reason']}" for r in failed[:3])
        raise InputError(f"{len(failed)} of {len(rows)} plate(s) failed ({listed}"
                         f"{'; ...' if len(failed) > 3 else ''})",
                         hint=f"see {csv_path}; fix them and run the same command again (finished plates are skipped)")


def _check_out_dir(out_dir: str) -> None:
    path = Path(out_dir)
    if path.exists() and not path.is_dir():
        raise InputError(f"-o {out_dir} is a file, not a folder", hint="give a folder for the jobs")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot make the output folder {out_dir}: {exc.strerror}",
                         hint="choose a writable -o") from None
    if not os.access(path, os.W_OK):
        raise InputError(f"the output folder {out_dir} is not writable", hint="choose a writable -o")


COMMANDS = [batch_command]
