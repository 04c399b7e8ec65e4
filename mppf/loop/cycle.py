"""The bend - measure - compare loop of one plate, resumable after a crash.

:func:`start_plate` plans the job and records the plate and its first cycle in the
history; :func:`run_loop` then drives every cycle through its states (see
:mod:`mppf.loop.history`) until the plate is in tolerance, the cycles run out, or the error
diverges:

    planned   -> press every step of the cycle's job          -> pressing -> pressed
    pressed   -> get the scan of the formed plate              -> scanned
    scanned   -> register it to the design, deviations         -> compared (+ decision)
    compared  -> correct the strokes, plan the next cycle      -> corrected | done

Each state is committed before the next action, so :func:`run_loop` called again on the
same plate (``mppf loop --resume``) continues where the last run stopped. A cycle found in
"pressing" is never pressed again: the press either finished the step or was stopped by
the PLC's watchdog when the master died, so the plate is measured as it is and the next
cycle corrects whatever happened.

The loop takes the press (:class:`mppf.core.presslink.PressLink`) and the scanner
(:class:`mppf.loop.scanners.Scanner`) as arguments and reports through a
:class:`mppf.core.progress.Reporter`; it prints nothing.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Callable

import numpy as np

from mppf.measure.compare import compare
from mppf.measure.mark import reference_mark
from mppf.correct.compensate import Correction, PreviousCycle, compensate, limit_correction
from mppf.core.errors import ConfigError, GeometryError, InputError, PressRefused
from mppf.loop.history import CycleRecord, History, PlateRecord
from mppf.geometry.io import PointCloud, read_points
from mppf.planning.job import Job, StepStrokes, grid_from_json, grid_to_json, load_job, save_job
from mppf.planning.plan import plan_job
from mppf.forming.precompensate import MIN_EXPLAINED, calibrated_correction
from mppf.planning.press import PressConfig, press_from_dict
from mppf.core.presslink import PressLink, StepResult
from mppf.core.progress import NULL_REPORTER, Reporter
from mppf.core.scanner import ScanContext, Scanner
from mppf.forming.material import Material
from mppf.core.transform import apply_tf

GROWTH_MARGIN_MM = 0.1
"""An RMS increase below this is scan noise, not growth (for the divergence rule)."""

#: Decisions recorded for a compared cycle; all but "continue" end the loop.
DECISIONS = ("continue", "in_tolerance", "max_cycles", "diverged")


@dataclass(frozen=True)
class LoopSettings:
    """When the loop stops and how hard it corrects.

    Attributes
    ----------
    tolerance_mm : float
        Largest absolute deviation accepted (mm).
    rms_tolerance_mm : float
        Largest RMS deviation accepted (mm). In tolerance = both limits met.
    max_cycles : int
        Press cycles at most (the first, planned one included).
    gain : float
        Displacement-adjustment gain lambda (with ``model_gain``: a factor on the
        springback-model correction).
    model_gain : bool
        Correct through the springback model with the nominal material of the job
        (:func:`mppf.correct.compensate.model_correction`: the slope of the springback law at the
        loaded curvature, per punch and per curvature component). Off: the secant gains
        of :func:`mppf.correct.compensate.compensate` (gain ``gain`` in the first correction).
    divergence_factor : float
        The loop stops as diverged when the RMS deviation grows by more than this
        factor from one cycle to the next, or grows two cycles in a row (see :func:`decide`).
    springback : bool
        Plan the first cycle with springback pre-compensation (over-bend).
    offset_mm : float or None
        Normal offset from the design surface to the scanned skin (mm); None = half the
        thickness (the design is the moulded mid-surface, the scanner sees the top skin).
    margin_mm : float or None
        Trim margin the flat plate is cut with (mm, see :func:`mppf.planning.plan.plan_job`); None =
        the press's ``[forming] margin_mm``. The scans carry it; the tolerance is judged on
        the net plate.
    calibrate : bool
        With ``model_gain``: fit the plate's effective yield stress to the measured cycles
        and solve the next strokes on the calibrated plate model
        (:func:`mppf.forming.precompensate.calibrated_correction`); the model step of
        :func:`mppf.correct.compensate.compensate` when the fit explains too little.
    """

    tolerance_mm: float = 2.5
    rms_tolerance_mm: float = 1.0
    max_cycles: int = 5
    gain: float = 1.0
    divergence_factor: float = 1.5
    springback: bool = True
    offset_mm: float | None = None
    model_gain: bool = True
    margin_mm: float | None = None
    calibrate: bool = True

    def __post_init__(self):
        for name in ("tolerance_mm", "rms_tolerance_mm", "gain", "divergence_factor"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
                raise InputError(f"loop setting {name} must be a positive number, got {value!r}")
        if self.divergence_factor <= 1.0:
            raise InputError(f"divergence_factor must exceed 1, got {self.divergence_factor}")
        if not (isinstance(self.max_cycles, int) and 1 <= self.max_cycles <= 50):
            raise InputError(f"max_cycles must be a whole number from 1 to 50, got {self.max_cycles!r}")

    def to_dict(self) -> dict:
        """JSON-ready dict (stored with the plate)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, doc: dict) -> LoopSettings:
        """Inverse of :meth:`to_dict` (unknown keys ignored)."""
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in doc.items() if k in names})


@dataclass(frozen=True)
class LoopResult:
    """Outcome of :func:`run_loop`.

    Attributes
    ----------
    plate_id : str
    status : str
        "in_tolerance", "max_cycles" or "diverged".
    cycles : list of CycleRecord
        Every cycle of the plate, as stored in the history.
    resumed_state : str or None
        State of the cycle the run started from when it continued an earlier run
        (None for a plate that no run had touched since planning).
    """

    plate_id: str
    status: str
    cycles: list
    resumed_state: str | None = None

    @property
    def last(self) -> CycleRecord:
        """The last cycle."""
        return self.cycles[-1]


#: Called with each cycle record once compared (and again when corrected or done),
#: plus the comparison when it was computed in this run (else None).
CycleCallback = Callable[[CycleRecord, object], None]


def decide(rms_history_mm: list[float], max_abs_mm: float, cycle: int, settings: LoopSettings) -> str:
    """The decision after a compared cycle.

    Parameters
    ----------
    rms_history_mm : list of float
        RMS deviation of every cycle so far, the current one last.
    max_abs_mm : float
        Largest absolute form deviation of the current cycle
        (:attr:`mppf.measure.compare.Comparison.form_max_abs_mm`).
    cycle : int
        The current cycle (1-based).

    Returns
    -------
    str
        "in_tolerance" when the largest absolute deviation and the RMS are both within
        their limits; "diverged" when the RMS (the robust measure: the largest
        deviation of a scan is one noisy point) grew by more than ``divergence_factor``
        since the last cycle, or grew two cycles in a row, each time by more than
        :data:`GROWTH_MARGIN_MM` (the scan's noise floor); "max_cycles" when no
        cycles are left; else "continue".
    """
    e = [float(v) for v in rms_history_mm]
    if max_abs_mm <= settings.tolerance_mm and e[-1] <= settings.rms_tolerance_mm:
        return "in_tolerance"
    if len(e) >= 2 and e[-1] > settings.divergence_factor * e[-2] and e[-1] > settings.rms_tolerance_mm:
        return "diverged"
    if len(e) >= 3 and e[-1] > e[-2] + GROWTH_MARGIN_MM and e[-2] > e[-3] + GROWTH_MARGIN_MM:
        return "diverged"
    if cycle >= settings.max_cycles:
        return "max_cycles"
    return "continue"


def new_plate_id(design_path) -> str:
    """A readable, unique-enough plate id: design file stem and the local time."""
    return f"{Path(design_path).stem}-{datetime.now().strftime('%Y%m%d-%H%M%S')}"


def start_plate(
    history: History,
    design: PointCloud,
    flat: PointCloud,
    press: PressConfig,
    thickness_mm: float,
    *,
    plate_id: str,
    work_dir,
    settings: LoopSettings = LoopSettings(),
    material: Material = Material(),
    setup: dict | None = None,
    reporter: Reporter = NULL_REPORTER,
) -> PlateRecord:
    """Plan a new plate and record it with its first cycle ("planned").

    Parameters
    ----------
    design, flat : PointCloud
        The design surface and its flat (unfolded) shape, read by :func:`mppf.geometry.io.read_points`
        (their paths and SHA-256 are recorded).
    press : PressConfig
    thickness_mm : float
    plate_id : str
    work_dir : path-like
        Folder for the plate's job files and scans (created).
    settings : LoopSettings
    material : Material
        Nominal plate material (springback pre-compensation of the first cycle).
    setup : dict, optional
        More to record with the plate (PLC URL, scanner, seed...), JSON-ready; a
        ``"units"`` entry (the length unit of the design file) is used to re-read it.

    Raises
    ------
    InputError
        Bad or mismatched inputs (from the planner), or the plate id already exists.
    """
    work_dir = Path(work_dir)
    # refuse a duplicate id before the (slow) planning
    history.check_new_plate(plate_id)
    # plan all steps of the first cycle, with springback pre-compensation
    reporter.info(f"planning plate {plate_id}")
    inputs = {"design": {"path": str(design.path), "sha256": design.sha256},
              "flat": {"path": str(flat.path), "sha256": flat.sha256}}
    job = plan_job(design.points, flat.points, press, thickness_mm, material=material,
                   springback=settings.springback, reporter=reporter, inputs=inputs, margin_mm=settings.margin_mm)
    try:
        work_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"cannot create the work folder {work_dir}: {exc.strerror}",
                         hint="give a writable folder with --work-dir") from None
    job_path = save_job(job, work_dir / "cycle-01.job.json")
    # record the plate, then its first cycle
    history.create_plate(
        plate_id,
        design_path=design.path.resolve(), design_sha256=design.sha256,
        flat_path=flat.path.resolve(), flat_sha256=flat.sha256,
        thickness_mm=thickness_mm, press=press.to_dict(),
        settings={"loop": settings.to_dict(), "work_dir": str(work_dir.resolve()), **(setup or {})},
    )
    history.add_cycle(plate_id, 1, job_path=job_path.resolve(), job_sha256=job.sha256(), steps=job.steps)
    return history.plate(plate_id)


def run_loop(
    history: History,
    plate_id: str,
    link: PressLink,
    scanner: Scanner,
    *,
    reporter: Reporter = NULL_REPORTER,
    on_cycle: CycleCallback | None = None,
) -> LoopResult:
    """Drive the plate's cycles from where the history stands until the loop ends.

    Parameters
    ----------
    history : History
    plate_id : str
        A plate recorded by :func:`start_plate`.
    link : PressLink
        The connected press.
    scanner : Scanner
    reporter : Reporter
    on_cycle : callable, optional
        ``on_cycle(record, comparison)`` after each compare and at the end of each cycle.

    Returns
    -------
    LoopResult

    Raises
    ------
    InputError
        The design file changed since the plate was planned, or the history refuses a
        state change; or a scan is unreadable (FileFormatError) or does not match the
        design (GeometryError): that scan is recorded as rejected, the cycle waits in
        "pressed" for another one.
    PressRefused, LimitError
        The press refused the step before any motion; the step is recorded as not
        started and is pressed when the loop is resumed.
    LinkError, PressFault, Cancelled
        From the press during a step; the cycle stays "pressing" and is measured, not
        pressed again, on resume.
    """
    plate = history.plate(plate_id)
    settings = LoopSettings.from_dict(plate.settings["loop"])
    press = press_from_dict(plate.press, source=f"history of plate {plate_id}")
    design = _read_checked(plate.design_path, plate.design_sha256, "design", plate.settings.get("units", "mm"))
    cycles = history.cycles(plate_id)
    ran_before = any(e.state != "planned" for e in history.events(plate_id) if e.cycle is not None)
    resumed = cycles[-1].state if ran_before else None
    number = cycles[-1].cycle
    while True:
        record = history.cycle(plate_id, number)
        if record.state == "planned":
            # press every step of the cycle (each step committed before and after)
            _press(history, record, press, link, reporter)
        elif record.state == "pressing":
            # interrupted while pressing: never press again, measure the plate as it is
            reporter.info(f"cycle {number} was interrupted at step {record.step_started} of {len(record.steps)}: "
                          "it is not pressed again; measuring the plate as it is")
            history.mark_pressed(plate_id, number, interrupted=True, detail="resumed after an interruption")
        elif record.state == "pressed":
            # measure: the scanner delivers a file of the formed plate
            path = Path(scanner.acquire(number, _scan_context(history, plate, record, press, reporter))).resolve()
            try:
                scan = read_points(path)
            except InputError as exc:  # unreadable: never taken again, wait for another
                history.reject_scan(plate_id, number, path, "", exc.message)
                raise
            history.mark_scanned(plate_id, number, path, scan.sha256)
        elif record.state == "scanned":
            # compare the scan with the design, decide
            try:
                comparison = _compare(plate, record, design, settings)
            except GeometryError as exc:  # not this plate (or units): back to "pressed", wait for another
                history.reject_scan(plate_id, number, record.scan_path, record.scan_sha256, exc.message)
                raise
            rms = [c.rms_mm for c in history.cycles(plate_id)[: number - 1]] + [comparison.rms_mm]
            # the plate's largest deviation is judged on its form (scanner point noise averaged
            # out, see mppf.measure.compare); the raw point extremes stay in the stored comparison
            decision = decide(rms, comparison.form_max_abs_mm, number, settings)
            history.mark_compared(
                plate_id, number, rms_mm=comparison.rms_mm, max_abs_mm=comparison.form_max_abs_mm,
                within_pct=comparison.within_tolerance_pct, punch_deviation_mm=comparison.punch_deviation_mm,
                comparison=_summary(comparison), decision=decision,
            )
            _notify(on_cycle, history.cycle(plate_id, number), comparison)
        elif record.state == "compared":
            if record.decision != "continue":
                history.mark_done(plate_id, number, record.decision)
            else:
                # correct the strokes and record the next cycle
                _plan_next(history, plate, record, press, settings)
            _notify(on_cycle, history.cycle(plate_id, number), None)
        elif record.state == "corrected":
            number += 1
        else:  # done
            return LoopResult(plate_id, record.decision, history.cycles(plate_id), resumed)


def _notify(on_cycle, record, comparison) -> None:
    if on_cycle is not None:
        on_cycle(record, comparison)


def _read_checked(path, sha256: str, what: str, units: str = "mm") -> PointCloud:
    cloud = read_points(path, units=units)
    if cloud.sha256 != sha256:
        raise InputError(
            f"the {what} file {path} changed since the plate was planned "
            f"(SHA-256 {cloud.sha256[:12]}..., recorded {sha256[:12]}...)",
            hint=f"restore the original {what} file, or start a new plate",
        )
    return cloud


def _press(history: History, record: CycleRecord, press: PressConfig, link: PressLink, reporter: Reporter) -> None:
    """Press the steps of a planned cycle, recording each before and after."""
    n = len(record.steps)
    if hasattr(link, "job_sha256"):  # the Modbus driver writes it into the audit log
        link.job_sha256 = record.job_sha256
    for index, step in enumerate(record.steps, start=1):
        reporter.info(f"cycle {record.cycle}: press step {index} of {n}")
        # committed before anything is sent: a crash from here on never presses this step again
        history.mark_step_started(record.plate_id, record.cycle, index)
        upper_mm, lower_mm = step.setpoints_mm(press)
        try:
            result = link.run_step(upper_mm, lower_mm, reporter=reporter)
        except (InputError, PressRefused) as exc:
            # refused before any motion (limits, verification, GO refused): the step may run later
            history.mark_step_not_started(record.plate_id, record.cycle, index, exc.message)
            raise
        history.mark_step_done(record.plate_id, record.cycle, index, _result_to_dict(result))
    history.mark_pressed(record.plate_id, record.cycle)


def _result_to_dict(result: StepResult) -> dict:
    return {
        "sequence": int(result.sequence),
        "max_error_mm": round(float(result.max_error_mm), 4),
        "duration_s": round(float(result.duration_s), 3),
        "actual_upper_mm": grid_to_json(result.actual_upper_mm),
        "actual_lower_mm": grid_to_json(result.actual_lower_mm),
    }


def _last_step(record: CycleRecord) -> StepStrokes:
    """The strokes the plate saw last in this cycle (the interrupted step after a crash)."""
    return record.steps[max(record.step_started, 1) - 1]


def _scan_context(history, plate, record, press, reporter) -> ScanContext:
    step = _last_step(record)
    if record.results and record.steps_done == record.step_started:
        upper_mm = grid_from_json(record.results[-1]["actual_upper_mm"])
        lower_mm = grid_from_json(record.results[-1]["actual_lower_mm"])
    else:  # read-back lost in a crash: the setpoints of the interrupted step
        upper_mm, lower_mm = step.setpoints_mm(press)
    since = datetime.fromisoformat(record.created_utc).timestamp()  # when the cycle was planned
    cycles = history.cycles(plate.plate_id)
    used = tuple([c.scan_path for c in cycles if c.scan_path and c.cycle != record.cycle]
                 + [r["path"] for c in cycles for r in c.rejected_scans])
    return ScanContext(
        plate_id=plate.plate_id, work_dir=Path(plate.settings["work_dir"]), since_s=since,
        upper_mm=upper_mm, lower_mm=lower_mm, active=step.active, used_paths=used, reporter=reporter,
    )


def _punch_xy(job: Job) -> np.ndarray:
    x, y = np.meshgrid(job.punch_x_mm, job.punch_y_mm)
    return np.stack([x, y], axis=-1)


def _load_cycle_job(record: CycleRecord) -> Job:
    job = load_job(record.job_path)
    if job.sha256() != record.job_sha256:
        raise ConfigError(
            f"job file {record.job_path} of cycle {record.cycle} changed since it was recorded",
            hint="restore it; the strokes are also in the history ('mppf history --json')",
        )
    return job


def _compare(plate: PlateRecord, record: CycleRecord, design: PointCloud, settings: LoopSettings):
    scan = _read_checked(record.scan_path, record.scan_sha256, "scan")
    job = _load_cycle_job(record)
    offset_mm = plate.thickness_mm / 2.0 if settings.offset_mm is None else settings.offset_mm
    return compare(
        design.points, scan.points, tolerance_mm=settings.tolerance_mm, offset_mm=offset_mm,
        punch_xy_mm=_punch_xy(job), tf_press_design=job.tf_press_design,
        reference_mark=reference_mark(record.scan_path, design.points, job),
        margin_mm=0.0 if job.layout is None else job.layout.margin_mm,
    )


def _summary(comparison) -> dict:
    doc = comparison.to_dict()
    doc.pop("punch_deviation_mm", None)  # stored in its own column
    return doc


def _plan_next(history: History, plate: PlateRecord, record: CycleRecord, press: PressConfig,
               settings: LoopSettings) -> None:
    """Correct the last strokes by the measured error and record the next cycle."""
    step = _last_step(record)
    # the cycle before gives the secant gain per punch
    previous = None
    if record.cycle > 1:
        before = history.cycle(plate.plate_id, record.cycle - 1)
        previous = PreviousCycle(lower_mm=_last_step(before).lower_mm, punch_error_mm=before.punch_deviation_mm)
    job = _load_cycle_job(record)
    nominal = job.layout.material if settings.model_gain and job.layout is not None else None
    correction = None
    if nominal and settings.calibrate:
        correction = _calibrated_correction(history, plate, record, press, job, nominal)
    if correction is None:
        correction = compensate(
            step.upper_mm, step.lower_mm, record.punch_deviation_mm, press=press, thickness_mm=plate.thickness_mm,
            gain=settings.gain, previous=previous, material=nominal,
        )
    active = step.active
    strokes = StepStrokes(np.where(active, correction.upper_mm, np.nan), np.where(active, correction.lower_mm, np.nan),
                          active)
    job = Job(press=job.press, thickness_mm=job.thickness_mm, steps=[strokes], tf_press_design=job.tf_press_design,
              tf_press_flat=job.tf_press_flat, punch_x_mm=job.punch_x_mm, punch_y_mm=job.punch_y_mm, layout=job.layout,
              extra={**job.extra, "loop": {"plate_id": plate.plate_id, "cycle": record.cycle + 1,
                                           "corrects_job_sha256": record.job_sha256}})
    path = save_job(job, Path(plate.settings["work_dir"]) / f"cycle-{record.cycle + 1:02d}.job.json")
    history.add_cycle(
        plate.plate_id, record.cycle + 1, job_path=path.resolve(), job_sha256=job.sha256(), steps=[strokes],
        gain=float(np.nanmean(correction.gain)), correction=_correction_to_dict(correction), previous_decision="continue",
    )


def _calibrated_correction(history: History, plate: PlateRecord, record: CycleRecord, press: PressConfig, job: Job,
                           nominal: Material) -> Correction | None:
    """The calibrated model's correction (:func:`mppf.forming.precompensate.calibrated_correction`), or None.

    None (the loop then takes the model step of :func:`mppf.correct.compensate.compensate`) when
    the job has no design heights at the punches (planned by an older version), a cycle
    was interrupted (its plate does not show its strokes), or the fitted model explains
    less than ``MIN_EXPLAINED`` of the measured deviations.
    """
    layout = job.layout
    records = history.cycles(plate.plate_id)[: record.cycle]
    if layout is None or layout.design_mid_mm is None or any(r.interrupted or r.punch_deviation_mm is None for r in records):
        return None
    step = _last_step(record)
    if any(not np.array_equal(_last_step(r).active, step.active) for r in records):
        return None
    cycles = [(_last_step(r).upper_mm, _last_step(r).lower_mm, r.punch_deviation_mm) for r in records]
    try:
        refined, fit = calibrated_correction(press, cycles, step.active, layout.design_mid_mm, layout.outline_mm,
                                             plate.thickness_mm, nominal)
    except (InputError, GeometryError):
        return None
    if fit.explained < MIN_EXPLAINED:
        return None
    active = step.active
    # the change from the strokes just pressed, held to the dimpling and stroke limits
    applied, clipped = limit_correction(press, np.where(active, step.upper_mm, np.nan),
                                        np.where(active, step.lower_mm, np.nan), refined.lower_mm - step.lower_mm)
    notes = list(refined.notes)
    if clipped.any():
        notes.append(f"correction limited at {int(clipped.sum())} punches (dimpling limit "
                     f"{press.max_neighbour_diff_mm:g} mm or stroke limits)")
    return Correction(upper_mm=np.where(active, step.upper_mm + applied, np.nan),
                      lower_mm=np.where(active, step.lower_mm + applied, np.nan), gain=np.where(active, 1.0, np.nan),
                      applied_mm=applied, clipped=clipped, notes=notes)


def _correction_to_dict(correction) -> dict:
    return {
        "gain": grid_to_json(correction.gain),
        "applied_mm": grid_to_json(correction.applied_mm),
        "clipped_punches": int(np.sum(correction.clipped)),
        "notes": list(correction.notes),
    }
