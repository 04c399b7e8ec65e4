"""Correcting a compared cycle: the next cycle's strokes from the deviations measured so far.

With the plate's nominal material (``model_gain``) and ``calibrate``, the plate model is
calibrated on every measured cycle (:func:`mppf.correct.calibrated.calibrated_step`), as
long as no cycle was interrupted and every cycle pressed the same punches; otherwise, or
when the calibration explains too little, the model step or the displacement adjustment
of :func:`mppf.correct.compensate.compensate`. The next cycle's job and its history record
are written together with the move of this cycle to "corrected".
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mppf.correct.calibrated import calibrated_step
from mppf.correct.compensate import compensate
from mppf.correct.result import Correction, PreviousCycle
from mppf.forming.material import Material
from mppf.loop.history import History
from mppf.loop.measuring import load_cycle_job
from mppf.loop.pressing import last_step
from mppf.loop.records import CycleRecord, PlateRecord
from mppf.loop.settings import LoopSettings
from mppf.loop.states import Decision
from mppf.planning.job import Job, StepStrokes, grid_to_json, save_job
from mppf.planning.press import PressConfig


def plan_next(history: History, plate: PlateRecord, record: CycleRecord, press: PressConfig,
              settings: LoopSettings) -> None:
    """Correct the last strokes by the measured error and record the next cycle ("planned").

    The compared cycle moves to "corrected" in the same transaction.
    """
    job = load_cycle_job(record)
    # correct the strokes just pressed by what was measured
    correction = next_correction(history, plate, record, press, settings, job)
    # the next cycle presses them on the same punches: its job file...
    active = last_step(record).active
    strokes = StepStrokes(np.where(active, correction.upper_mm, np.nan), np.where(active, correction.lower_mm, np.nan),
                          active)
    loop = {"plate_id": plate.plate_id, "cycle": record.cycle + 1, "corrects_job_sha256": record.job_sha256}
    job = Job(press=job.press, thickness_mm=job.thickness_mm, steps=[strokes], tf_press_design=job.tf_press_design,
              tf_press_flat=job.tf_press_flat, punch_x_mm=job.punch_x_mm, punch_y_mm=job.punch_y_mm, layout=job.layout,
              extra={**job.extra, "loop": loop})
    path = save_job(job, Path(plate.settings["work_dir"]) / f"cycle-{record.cycle + 1:02d}.job.json")
    # ... and its record
    history.add_cycle(
        plate.plate_id, record.cycle + 1, job_path=path.resolve(), job_sha256=job.sha256(), steps=[strokes],
        gain=float(np.nanmean(correction.gain)), correction=correction_to_dict(correction),
        previous_decision=Decision.CONTINUE,
    )


def next_correction(history: History, plate: PlateRecord, record: CycleRecord, press: PressConfig,
                    settings: LoopSettings, job: Job) -> Correction:
    """The correction of the cycle's last step: calibrated when it may and can be, else :func:`compensate`."""
    step = last_step(record)
    nominal = job.layout.material if settings.model_gain and job.layout is not None else None
    correction = None
    if nominal and settings.calibrate:
        correction = _calibrated(history, plate, record, press, job, nominal)
    if correction is None:
        correction = compensate(
            step.upper_mm, step.lower_mm, record.punch_deviation_mm, press=press, thickness_mm=plate.thickness_mm,
            gain=settings.gain, previous=_previous(history, record), material=nominal,
        )
    return correction


def _previous(history: History, record: CycleRecord) -> PreviousCycle | None:
    """The cycle before, for the secant gain per punch (None for the first cycle)."""
    if record.cycle == 1:
        return None
    before = history.cycle(record.plate_id, record.cycle - 1)
    return PreviousCycle(lower_mm=last_step(before).lower_mm, punch_error_mm=before.punch_deviation_mm)


def _calibrated(history: History, plate: PlateRecord, record: CycleRecord, press: PressConfig, job: Job,
                nominal: Material) -> Correction | None:
    """:func:`mppf.correct.calibrated.calibrated_step` on every measured cycle, or None.

    None (the loop then takes :func:`compensate`) when a cycle was interrupted (its plate
    does not show its strokes) or not measured, when the cycles pressed different punches,
    or when :func:`calibrated_step` declines.
    """
    records = history.cycles(plate.plate_id)[: record.cycle]
    if any(r.interrupted or r.punch_deviation_mm is None for r in records):
        return None
    step = last_step(record)
    if any(not np.array_equal(last_step(r).active, step.active) for r in records):
        return None
    cycles = [(last_step(r).upper_mm, last_step(r).lower_mm, r.punch_deviation_mm) for r in records]
    return calibrated_step(press, cycles, step, job.layout, plate.thickness_mm, nominal)


def correction_to_dict(correction: Correction) -> dict:
    """The correction as stored with the next cycle."""
    return {
        "gain": grid_to_json(correction.gain),
        "applied_mm": grid_to_json(correction.applied_mm),
        "clipped_punches": int(np.sum(correction.clipped)),
        "notes": list(correction.notes),
    }
