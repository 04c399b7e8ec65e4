"""A new plate in the loop: plan its first cycle and record it in the history."""

from __future__ import annotations

from datetime import datetime
from pathlib import Path

from mppf.core.errors import InputError
from mppf.core.progress import NULL_REPORTER, Reporter
from mppf.core.validate import safe_name
from mppf.geometry.read import PointCloud
from mppf.loop.history import History
from mppf.loop.options import LoopOptions, PlateFiles, PlateInputs
from mppf.loop.records import PlateRecord
from mppf.loop.section_steps import cycle_steps
from mppf.loop.settings import LoopSettings
from mppf.model.job import Job
from mppf.model.material import Material
from mppf.model.plan_options import PlanOptions
from mppf.model.press import PressConfig
from mppf.planning.job import save_job
from mppf.planning.sectional import plan_plate


def new_plate_id(design_path) -> str:
    """A readable, unique-enough plate id: design file stem (made safe) and the local time."""
    return f"{safe_name(Path(design_path).stem)[:48]}-{datetime.now().strftime('%Y%m%d-%H%M%S')}"


def plan_first_cycle(design: PointCloud, flat: PointCloud, press: PressConfig, thickness_mm: float, *,
                     settings: LoopSettings = LoopSettings(), material: Material = Material(),
                     reporter: Reporter = NULL_REPORTER) -> Job:
    """The job of a plate's first cycle: every step, springback pre-compensated unless the settings say no.

    A plate larger than the bed is planned in sections (:func:`mppf.planning.sectional.plan_plate`).

    Parameters
    ----------
    design, flat : PointCloud
        The design surface and its flat (unfolded) shape (their paths and SHA-256 go into
        the job's inputs).
    press : PressConfig
    thickness_mm : float
    settings : LoopSettings
        ``springback``, ``yield_uncertainty_pct`` (the first press planned for the weakest plate
        of the declared yield range: it under-bends) and ``margin_mm`` are used.
    material : Material
        Nominal plate material.

    Raises
    ------
    InputError
        Bad or mismatched inputs (from the planner).
    """
    inputs = {"design": {"path": str(design.path), "sha256": design.sha256},
              "flat": {"path": str(flat.path), "sha256": flat.sha256}}
    options = PlanOptions(material=material, springback=settings.springback,
                          yield_uncertainty_pct=settings.yield_uncertainty_pct, margin_mm=settings.margin_mm)
    return plan_plate(design.points, flat.points, press, thickness_mm, options, reporter=reporter, inputs=inputs)


def plate_reach(press: PressConfig, job: Job, design_points, tolerance_mm: float) -> dict | None:
    """What the press can make of the planned plate (:func:`mppf.forming.reach.reach_estimate`) as a dict, or
    None for a plate planned in sections (each section has its own outer punches)."""
    from mppf.forming.reach import reach_estimate
    from mppf.loop.section_steps import is_sectional

    if is_sectional(job) or job.layout is None:
        return None
    return reach_estimate(press, job, design_points, tolerance_mm).to_dict()


def record_plate(history: History, plate: PlateInputs, job: Job, *, plate_id: str, work_dir,
                 options: LoopOptions = LoopOptions()) -> PlateRecord:
    """Record a plate with its first cycle ("planned") pressing ``job``; its job file goes into ``work_dir``.

    Parameters
    ----------
    history : History
    plate : PlateInputs
        Design, flat, press and thickness, as given to :func:`plan_first_cycle`.
    job : Job
        The first cycle's job (:func:`plan_first_cycle`).
    plate_id : str
    work_dir : path-like
        Folder for the plate's job files and scans (created).
    options : LoopOptions
        Its ``settings`` and ``setup`` are recorded with the plate.

    Raises
    ------
    InputError
        The plate id already exists, or the work folder cannot be created.
    """
    work_dir = Path(work_dir)
    history.check_new_plate(plate_id)
    try:
        work_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the work folder {work_dir}: {exc.strerror}",
                         hint="give a writable folder with --work-dir") from None
    job_path = save_job(job, work_dir / "cycle-01.job.json")
    files = PlateFiles(design_path=plate.design.path.resolve(), design_sha256=plate.design.sha256,
                       flat_path=plate.flat.path.resolve(), flat_sha256=plate.flat.sha256)
    settings = {"loop": options.settings.to_dict(), "work_dir": str(work_dir.resolve()), **(options.setup or {})}
    # the plate and its first cycle in one transaction: a crash leaves both or neither
    with history.transaction():
        history.create_plate(plate_id, files, thickness_mm=plate.thickness_mm, press=plate.press.to_dict(),
                             settings=settings)
        history.add_cycle(plate_id, 1, job_path=job_path.resolve(), job_sha256=job.sha256(), steps=cycle_steps(job))
    return history.plate(plate_id)


def start_plate(history: History, plate: PlateInputs, *, plate_id: str, work_dir,
                options: LoopOptions = LoopOptions(), reporter: Reporter = NULL_REPORTER) -> PlateRecord:
    """Plan a new plate and record it with its first cycle ("planned").

    Parameters
    ----------
    history : History
    plate : PlateInputs
        Design and flat (their paths and SHA-256 are recorded), press and thickness.
    plate_id : str
    work_dir : path-like
        Folder for the plate's job files and scans (created).
    options : LoopOptions
        The loop settings (the first cycle's springback, yield uncertainty and margin), the nominal
        material, and what else to record (:func:`record_plate`).
    reporter : Reporter

    Raises
    ------
    InputError
        Bad or mismatched inputs (from the planner), or the plate id already exists.
    """
    # refuse a duplicate id before the (slow) planning
    history.check_new_plate(plate_id)
    # plan all steps of the first cycle, with springback pre-compensation
    reporter.info(f"planning plate {plate_id}")
    job = plan_first_cycle(plate.design, plate.flat, plate.press, plate.thickness_mm, settings=options.settings,
                           material=options.material, reporter=reporter)
    # record the plate, then its first cycle
    return record_plate(history, plate, job, plate_id=plate_id, work_dir=work_dir, options=options)
