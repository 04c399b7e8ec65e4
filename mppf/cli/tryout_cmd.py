"""``mppf tryout``: the virtual try-out of a job on the FE plate before any steel is pressed.

The job's first cycle (every step of it, in order, the tips where the job sets them) is pressed on
the FE plate computed by CalculiX (:class:`mppf.sim.fe.plate.FEPlate`, the plate's true material
drawn from --seed), its top skin is taken as a noise-free scan (with the reference-corner mark)
and compared with the design exactly as ``mppf compare --job`` compares a scan: form max, RMS,
the deviation map and the HTML report, all written into the output folder.
"""

from __future__ import annotations

import time
from pathlib import Path

import click

from mppf.cli._common import console, units_option
from mppf.core.errors import InputError
from mppf.core.progress import NullReporter


@click.command("tryout")
@click.argument("job_path", metavar="JOB", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--design", "design_path", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="The design plate (point or mesh file) the job was planned for.")
@click.option("--flat", "flat_path", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="The flat plate (point file, flat coordinates) the job presses.")
@click.option("-o", "--out", "out_dir", type=click.Path(file_okay=False, path_type=Path), default=Path("tryout"),
              show_default=True, help="Output folder: the predicted scan, deviation map and report.html.")
@click.option("--seed", type=int, default=0, show_default=True,
              help="Seed of the plate's true material and thickness (scatter around the nominal).")
@click.option("--cells-per-pitch", type=int, default=None,
              help="Element edges between neighbouring punch axes [default: the FE plate's, 1].")
@click.option("--layers", type=int, default=None, help="Elements through the thickness [default: 4].")
@click.option("--steps", "which_steps", type=click.Choice(["all", "last"]), default="all", show_default=True,
              help="Press every step of the first cycle in order, or only its last step straight from the flat "
                   "plate (one ccx run; the fallback when a later step of a strongly bent plate does not converge, "
                   "docs/simulator-fe.md).")
@units_option
def tryout(job_path, design_path, flat_path, out_dir, seed, cells_per_pitch, layers, which_steps, units):
    """Predict with the FE plate (CalculiX) the shape JOB's first cycle presses, and compare it with the design.

    Prints the form max and RMS of the predicted plate against the design and writes the deviation
    map (deviation.png) and the report (report.html) into --out; the exit code is mppf compare's
    (0 in tolerance, 5 out of tolerance, 6 needs review). Needs CalculiX (Debian package
    calculix-ccx); exit 2 without it, for unreadable files or a job pressed in sections.
    """
    from mppf.core.validate import check_number
    from mppf.sim.fe.ccx import find_ccx

    check_number("--seed", seed, low=0, integer=True, hint="give a whole number, 0 or more")
    options = {}
    if cells_per_pitch is not None:
        options["cells_per_pitch"] = check_number("--cells-per-pitch", cells_per_pitch, low=1, high=8, integer=True)
    if layers is not None:
        options["layers"] = check_number("--layers", layers, low=1, high=8, integer=True)
    find_ccx()
    started = time.monotonic()
    scan, job = _predicted_scan(job_path, flat_path, out_dir, seed, options, units, which_steps == "last")
    what = f"{len(job.steps)} step(s)" if which_steps == "all" else f"last of {len(job.steps)} step(s)"
    console.print(f"FE plate: the first cycle's {what} pressed in {time.monotonic() - started:.0f} s; "
                  "compared with the design:")
    from mppf.cli import main

    code = main(["compare", str(design_path), str(scan), "--job", str(job_path), "--units", units,
                 "--plot", str(out_dir / "deviation.png"), "--report", str(out_dir / "report.html")])
    console.print(f"try-out done in {time.monotonic() - started:.0f} s; files in {out_dir}")
    if code:  # as mppf compare: 5 out of tolerance, 6 needs review, 2 bad input
        raise click.exceptions.Exit(code)


def _predicted_scan(job_path: Path, flat_path: Path, out_dir: Path, seed: int, options: dict, units: str,
                    last_only: bool = False):
    """Press the job's first cycle on the FE plate and write its top skin as a scan (with its mark file)."""
    import numpy as np

    from mppf.core.scanner import PressedStep, ScanContext
    from mppf.geometry.read import read_points
    from mppf.planning.job import load_job
    from mppf.sim.shop import STATE_FILE, SimulatedPlateScanner

    job = load_job(job_path)
    if job.sections:
        raise InputError(f"the job {job_path} presses the plate in {len(job.sections)} sections; the FE plate "
                         "presses one placement", hint="try out a job that fits the bed")
    flat = read_points(flat_path, units=units)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the output folder {out_dir}: {exc.strerror}") from None
    try:  # a try-out presses a new plate: the state an earlier try-out left in the folder is not taken up
        (out_dir / STATE_FILE).unlink(missing_ok=True)
    except OSError as exc:
        raise InputError(f"cannot remove the earlier try-out's plate {out_dir / STATE_FILE}: {exc.strerror}",
                         hint="give another output folder (-o)") from None
    scanner = SimulatedPlateScanner.for_job(job.press, job.thickness_mm, job, flat.points, seed=seed,
                                            plate_model="fe", plate_options=options, noise_mm=0.0,
                                            occlusion_fraction=0.0, outlier_fraction=0.0)
    steps = tuple(PressedStep(1, k, *step.setpoints_mm(job.press), np.asarray(step.active, dtype=bool))
                  for k, step in enumerate(job.steps, start=1))
    if last_only:
        steps = steps[-1:]
    context = ScanContext(plate_id="tryout", work_dir=out_dir, since_s=0.0, upper_mm=steps[-1].upper_mm,
                          lower_mm=steps[-1].lower_mm, active=steps[-1].active, steps=steps, reporter=_Progress())
    return scanner.acquire(1, context), job


class _Progress(NullReporter):
    """The reporter of the try-out (:class:`mppf.core.progress.Reporter`): ccx's progress lines on the console."""

    def start(self, task: str, total: float | None = None) -> None:
        console.print(task, markup=False, soft_wrap=True)

    def info(self, message: str) -> None:
        console.print(message, markup=False, soft_wrap=True)


COMMANDS = [tryout]
