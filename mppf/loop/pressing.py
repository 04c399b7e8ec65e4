"""Pressing a planned cycle, step by step, and what the plate saw last (for its scan).

Each step is committed in the history before anything is sent to the press and again with
the press's read-back when it is done, so a crash never presses a step twice
(:meth:`mppf.loop.history.History.mark_step_started`). A step the press refused before any
motion (limits, verification, GO refused) is recorded as not started and may run later.
"""

from __future__ import annotations

from datetime import datetime
from pathlib import Path

from mppf.core.errors import InputError, PressRefused
from mppf.core.presslink import PressLink, StepResult
from mppf.core.progress import Reporter
from mppf.core.scanner import PressedStep, ScanContext
from mppf.loop.history import History
from mppf.loop.records import CycleRecord, PlateRecord, load_cycle_job
from mppf.loop.section_steps import placed_steps
from mppf.model.job_parts import (
    StepStrokes,
    grid_from_json,
    grid_to_json,
    steps_to_json,
)
from mppf.model.press import PressConfig


def press_cycle(history: History, record: CycleRecord, press: PressConfig, link: PressLink,
                reporter: Reporter) -> None:
    """Press the steps of a planned cycle, recording each before and after; the cycle ends "pressed".

    Raises
    ------
    InputError, PressRefused
        Refused before any motion: the step is recorded as not started.
    LinkError, PlcError, PressFault, Cancelled
        From the press during a step: the cycle stays "pressing" (never pressed again).
    """
    link.job_sha256 = record.job_sha256  # the press driver writes it into the audit log
    for index in range(1, len(record.steps) + 1):
        press_step(history, record, press, link, reporter, index)
    history.mark_pressed(record.plate_id, record.cycle)


def press_step(history: History, record: CycleRecord, press: PressConfig, link: PressLink, reporter: Reporter,
               index: int, what: str = "") -> None:
    """Press step ``index`` (1-based) of the cycle: recorded as started before anything is sent, done with its
    read-back.

    ``what`` is said after the step's number (e.g. "(section 2, step 1 of 2)").

    Raises
    ------
    InputError, PressRefused
        Refused before any motion: the step is recorded as not started.
    LinkError, PlcError, PressFault, Cancelled
        From the press during the step: it stays started, not done.
    """
    step = record.steps[index - 1]
    check_step_is_sealed(record, index, press)  # the history's copy of the strokes is not trusted alone
    reporter.info(f"cycle {record.cycle}: press step {index} of {len(record.steps)}" + (f" {what}" if what else ""))
    # committed before anything is sent: a crash from here on never presses this step again
    history.mark_step_started(record.plate_id, record.cycle, index)
    upper_mm, lower_mm = step.setpoints_mm(press)
    try:
        result = link.run_step(upper_mm, lower_mm, reporter=reporter)
    except (InputError, PressRefused) as exc:
        # refused before any motion (limits, verification, GO refused): the step may run later
        history.mark_step_not_started(record.plate_id, record.cycle, index, exc.message)
        raise
    history.mark_step_done(record.plate_id, record.cycle, index, result_to_dict(result))


def check_step_is_sealed(record: CycleRecord, index: int, press: PressConfig | None = None) -> None:
    """Refuse to press a step whose strokes in the history differ from the cycle's sealed job file.

    The job file's seal and recorded hash are checked (:func:`load_cycle_job`), then the step
    ``index`` (1-based, over every section's steps) and the number of steps against it, and the
    press the setpoints are made for (parking heights) against the job's.

    Raises
    ------
    ConfigError
        The job's seal or hash does not match, or the history's steps are not the job's.
    """
    from mppf.core.errors import ConfigError
    from mppf.loop.section_steps import cycle_steps

    job = load_cycle_job(record)
    if press is not None and press != job.press:
        raise ConfigError(f"cycle {record.cycle} of plate {record.plate_id}: the press recorded in the history is not "
                          f"the press of its sealed job {record.job_path}; nothing was sent to the press",
                          hint="the history was edited or damaged: restore it from its backup, or start the plate "
                               "again")
    planned = cycle_steps(job)
    if len(planned) != len(record.steps) or \
            steps_to_json([planned[index - 1]]) != steps_to_json([record.steps[index - 1]]):
        raise ConfigError(f"cycle {record.cycle} of plate {record.plate_id}: step {index} in the history is not step "
                          f"{index} of its sealed job {record.job_path} ({len(record.steps)} step(s) recorded, "
                          f"{len(planned)} in the job); nothing was sent to the press",
                          hint="the history was edited or damaged: restore it from its backup, or start the plate "
                               "again")


def close_cut_step(history: History, record: CycleRecord, press: PressConfig) -> CycleRecord:
    """Record the step a crash cut short as over, unfinished (its setpoints, ``complete: false``), so the cycle's
    later steps may be pressed (a plate pressed in sections); the step itself is never pressed again.

    Returns the cycle as recorded now (unchanged when no step was cut short).
    """
    if record.step_started <= record.steps_done:
        return record
    index = record.step_started
    upper_mm, lower_mm = record.steps[index - 1].setpoints_mm(press)
    history.mark_step_done(record.plate_id, record.cycle, index, {
        "sequence": -1, "complete": False, "max_error_mm": None, "duration_s": None,
        "actual_upper_mm": grid_to_json(upper_mm), "actual_lower_mm": grid_to_json(lower_mm)})
    return history.cycle(record.plate_id, record.cycle)


def result_to_dict(result: StepResult) -> dict:
    """A step's read-back as stored in the history."""
    return {
        "sequence": int(result.sequence),
        "max_error_mm": round(float(result.max_error_mm), 4),
        "duration_s": round(float(result.duration_s), 3),
        "actual_upper_mm": grid_to_json(result.actual_upper_mm),
        "actual_lower_mm": grid_to_json(result.actual_lower_mm),
    }


def last_step(record: CycleRecord) -> StepStrokes:
    """The strokes the plate saw last in this cycle (the interrupted step after a crash)."""
    return record.steps[max(record.step_started, 1) - 1]


def scan_context(history: History, plate: PlateRecord, record: CycleRecord, press: PressConfig,
                 reporter: Reporter) -> ScanContext:
    """What the scanner may want to know about the cycle: every step the press did, the last one's tips, more.

    The steps of a plate pressed in sections carry their section and where the plate lay for it
    (:func:`mppf.loop.section_steps.placed_steps`).
    """
    steps = list(placed_steps(pressed_steps(record, press), load_cycle_job(record)))
    last = steps[-1] if steps else None
    if last is None:  # nothing was pressed (cannot happen in the loop): the first step's setpoints
        upper_mm, lower_mm = record.steps[0].setpoints_mm(press)
        active = record.steps[0].active
    else:
        upper_mm, lower_mm, active = last.upper_mm, last.lower_mm, last.active
    since = datetime.fromisoformat(record.created_utc).timestamp()  # when the cycle was planned
    cycles = history.cycles(plate.plate_id)
    used = tuple([c.scan_path for c in cycles if c.scan_path and c.cycle != record.cycle]
                 + [r["path"] for c in cycles for r in c.rejected_scans])
    return ScanContext(
        plate_id=plate.plate_id, work_dir=Path(plate.settings["work_dir"]), since_s=since,
        upper_mm=upper_mm, lower_mm=lower_mm, active=active, used_paths=used, steps=tuple(steps),
        reporter=reporter,
    )


def pressed_steps(record: CycleRecord, press: PressConfig) -> list[PressedStep]:
    """The steps of a cycle the press did, in order, as it did them.

    Every step recorded as done, with the tips read back after it (a step cut short and
    closed by :func:`close_cut_step`: its setpoints, ``complete=False``); then the step that
    was started but not finished (an interruption during its motion), with its setpoints
    and ``complete=False``.
    """
    steps = []
    for index, result in enumerate(record.results[: record.steps_done], start=1):
        # a step a crash cut short and the cycle went on after (:func:`close_cut_step`): its setpoints
        steps.append(PressedStep(record.cycle, index, grid_from_json(result["actual_upper_mm"]),
                                 grid_from_json(result["actual_lower_mm"]), record.steps[index - 1].active,
                                 complete=result.get("complete", True)))
    if record.step_started > record.steps_done:  # interrupted in motion: the read-back is lost
        step = record.steps[record.step_started - 1]
        upper_mm, lower_mm = step.setpoints_mm(press)
        steps.append(PressedStep(record.cycle, record.step_started, upper_mm, lower_mm, step.active, complete=False))
    return steps
