"""Correcting a compared cycle: the next cycle's strokes from the deviations measured so far.

The loop has one correction, :func:`mppf.correct.step.correct_step`: it learns from every step
the press did and every scan (:func:`mppf.correct.learned.learned_correction`: the plate's
plastic memory replayed, its yield stress and hardening fitted, its response learned by secant
updates, aimed short of the design, inside a trust region), sized by the step policy; an
interrupted cycle counts with the steps recorded as done (read-back tips) and the one stopped
on its way. Cycles that pressed other punches than the last one count at the punches the last
one pressed (:class:`mppf.correct.punch_grid.PunchGrid` fills the others). When the correction
finds no way on, the loop stops with a verdict (:func:`mppf.correct.verdict.convergence_verdict`)
instead of pressing on to the cycle limit. The next cycle's job and its history record are
written together with the move of this cycle to "corrected".

The correction needs the design's heights at the punches and the nominal material in the job's
plate layout (every job planned by the loop has them); :func:`check_correctable` refuses a plate
whose job lacks the heights when the loop starts, and :func:`corrected_plate` takes the material
recorded with the plate for an older job without it.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from mppf.core.errors import InputError
from mppf.correct.inputs import CorrectedPlate, CorrectionHistory
from mppf.correct.learned import LearnedCorrection, steps_towards
from mppf.correct.memory import PressedCycle
from mppf.correct.policy import DEFAULT_NOISE_MM
from mppf.correct.step import Tolerances, correct_step, outcome
from mppf.correct.verdict import Verdict
from mppf.loop.history import History
from mppf.loop.pressing import pressed_steps
from mppf.loop.records import CycleRecord, PlateRecord, load_cycle_job
from mppf.loop.settings import LoopSettings
from mppf.loop.states import Decision
from mppf.model.job import Job
from mppf.model.job_parts import grid_from_json, grid_to_json
from mppf.model.job_provenance import LoopProvenance
from mppf.model.material import MATERIALS, Material
from mppf.model.press import PressConfig
from mppf.planning.job import save_job
from mppf.planning.steps import flat_heights


def plan_next(history: History, plate: PlateRecord, record: CycleRecord, press: PressConfig,
              settings: LoopSettings) -> Verdict | None:
    """Correct the last strokes by the measured error and record the next cycle ("planned").

    The compared cycle moves to "corrected" in the same transaction.

    Returns
    -------
    Verdict or None
        Why the plate cannot be brought into tolerance (nothing is planned; the loop ends
        it as "cannot_converge"), or None: the next cycle is planned.
    """
    job = load_cycle_job(record)
    records = history.cycles(plate.plate_id)[: record.cycle]
    final = record.steps[-1]  # the strokes this cycle aimed at (all of them, even if interrupted)
    # 1. every step the press did, cycle by cycle, and what the scanner measured after each cycle
    cycles = [c for c in (pressed_cycle(r, press) for r in records) if c.steps_mid_mm]
    # 2. the next strokes, learned from all of it, sized by what the plate showed (mppf.correct.step)
    measured = [r for r in records if r.punch_deviation_mm is not None and r.rms_mm is not None]
    outcomes = [outcome(r.max_abs_mm, r.rms_mm, r.punch_deviation_mm, _promised(r)) for r in measured]
    strokes = [(r.steps[-1].upper_mm, r.steps[-1].lower_mm) for r in measured]
    edge = grid_from_json((record.comparison or {}).get("punch_edge_mm"))  # the net edge beyond the outer rows
    noise = ((record.comparison or {}).get("form") or {}).get("noise_mm") or DEFAULT_NOISE_MM
    tolerances = Tolerances(settings.tolerance_mm, settings.rms_tolerance_mm, float(noise))
    corrected = corrected_plate(job.layout, plate, press, final.active)
    step = correct_step(corrected, CorrectionHistory(cycles, outcomes, strokes, edge), tolerances)
    # 3. stop with a verdict when it finds no way on
    if step.verdict is not None:
        return step.verdict
    learned = step.learned
    # 4. the next cycle's steps, from the tips the plate last held to the new strokes
    steps = steps_towards(press, _held(record, press, plate.thickness_mm), learned, final.active)
    job = _next_job(job, steps, plate, record)
    path = save_job(job, Path(plate.settings["work_dir"]) / f"cycle-{record.cycle + 1:02d}.job.json")
    history.add_cycle(
        plate.plate_id, record.cycle + 1, job_path=path.resolve(), job_sha256=job.sha256(), steps=steps,
        gain=float(np.mean(learned.gains)) if learned.gains.size else 1.0, correction=step_to_dict(step),
        previous_decision=Decision.CONTINUE,
    )
    return None


def check_correctable(job: Job, plate: PlateRecord) -> None:
    """Refuse, before anything is pressed, a plate whose job lacks what the correction needs.

    The correction (:func:`mppf.correct.step.correct_step`) aims at the design's mid-surface heights at
    the punches (``PlateLayout.design_mid_mm``, every section's for a plate in sections); a job written by
    an older mppf may lack them. The nominal material is not checked: :func:`corrected_plate` takes the
    one recorded with the plate when the job has none.

    Raises
    ------
    InputError
        The job (or a section of it) has no plate layout or no design heights at the punches (exit 2).
    """
    parts = [(f"section {s.index}", s.layout) for s in job.sections] if job.sections else [("its job", job.layout)]
    for name, layout in parts:
        if layout is None or layout.design_mid_mm is None:
            raise InputError(
                f"plate {plate.plate_id}: {name} carries no design heights at the punches (design_mid_mm), which "
                "the loop's correction aims at; the job was written by an older mppf",
                hint="start the plate again with this mppf (mppf loop DESIGN FLAT ... under a new --plate-id): "
                     "it plans the job with them")


def corrected_plate(layout, plate: PlateRecord, press: PressConfig, active) -> CorrectedPlate:
    """What :func:`mppf.correct.step.correct_step` corrects: the layout's design heights and material.

    Parameters
    ----------
    layout : PlateLayout
        The job's (or a section's) plate layout, with its design heights at the punches
        (:func:`check_correctable`).
    plate : PlateRecord
        Its thickness, and the nominal material recorded with it (``settings["material"]``, default
        ``"steel"``), taken when the layout (of an older job) has none.
    press : PressConfig
    active : (rows, cols) bool
        The punches of the cycle just pressed.

    Returns
    -------
    CorrectedPlate
    """
    material = layout.material or MATERIALS.get(plate.settings.get("material", "steel"), Material())
    return CorrectedPlate(press, layout.design_mid_mm, plate.thickness_mm, material, active)


def _promised(record: CycleRecord):
    """The deviation at the punches the correction that made this cycle predicted (None: the first cycle)."""
    predicted = (record.correction or {}).get("predicted_mm")
    return None if predicted is None else grid_from_json(predicted)


def pressed_cycle(record: CycleRecord, press: PressConfig) -> PressedCycle:
    """A cycle as the press did it (:func:`mppf.loop.pressing.pressed_steps`) and as it was measured."""
    steps = pressed_steps(record, press)
    mids = [np.where(s.active, 0.5 * (s.upper_mm + s.lower_mm), np.nan) for s in steps]
    interrupted = bool(steps) and not steps[-1].complete
    return PressedCycle(mids, record.punch_deviation_mm, interrupted=interrupted)


def _held(record: CycleRecord, press: PressConfig, thickness_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """The tips of the last step the press finished in this cycle (read back), else the flat plate's."""
    done = [s for s in pressed_steps(record, press) if s.complete]
    if done:
        return done[-1].upper_mm, done[-1].lower_mm
    up0, lo0 = flat_heights(thickness_mm)
    return np.full(press.shape, up0), np.full(press.shape, lo0)


def learned_to_dict(learned: LearnedCorrection) -> dict:
    """The learned correction as stored with the next cycle."""
    return {
        "strategy": "learned",
        "applied_mm": grid_to_json(learned.change_mm),
        "predicted_mm": grid_to_json(learned.predicted_mm),
        "predicted_rms_mm": round(learned.predicted_rms_mm, 4),
        "yield_stress_mpa": round(learned.calibration.law.yield_stress_mpa, 1),
        "hardening_mpa": round(learned.calibration.law.hardening_mpa, 1),
        "response_gains": [round(float(g), 4) for g in learned.gains],
        "clipped_punches": int(np.sum(learned.clipped)),
        "unreached_punches": int(np.sum(learned.unreached)),
        "notes": list(learned.notes),
    }


def step_to_dict(step) -> dict:
    """The correction step (:class:`mppf.correct.step.CorrectionStep`) as stored with the next cycle."""
    return {**learned_to_dict(step.learned), "share": round(step.plan.share, 4), "base_cycle": step.plan.base + 1,
            "measured_response": [round(float(r), 4) for r in step.plan.ratios],
            "measured_edge_response": [round(float(r), 4) for r in step.plan.edge_ratios]}


def _next_job(job: Job, steps: list, plate: PlateRecord, record: CycleRecord) -> Job:
    """The job of the next cycle: ``job`` with the corrected ``steps``, recording which cycle's job it corrects.

    The planner's reports stay those of the first cycle (the job checks skip their step counts in a job
    with ``loop`` provenance); the seal is made again when the job is saved.
    """
    loop = LoopProvenance(plate_id=plate.plate_id, cycle=record.cycle + 1, corrects_job_sha256=record.job_sha256)
    return dataclasses.replace(job, steps=steps, sections=None, loop=loop, seal=None)
