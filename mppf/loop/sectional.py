"""The loop on a plate larger than the bed: press every section, one scan, correct every section.

A cycle of a sectional job (version 3, :mod:`mppf.model.job_sections`):

1. every section's steps in pressing order (:func:`press_sections`); before a section the plate is
   shifted to its placement: the ``place`` callback tells the operator (and on a real press waits
   for the confirmation, as ``mppf press`` does); the steps of all sections are one list in the
   history (:mod:`mppf.loop.section_steps`), so a resumed cycle presses only the steps not recorded
   as started, in whichever section (a step a crash cut short is closed, never pressed again, and
   the cycle goes on with the next one: the plate is measured whole);
2. one scan of the whole plate, compared with the whole design (as one piece: :mod:`mppf.loop.measuring`);
3. the deviations at every section's punches (:func:`section_deviations`: the punch axes taken to
   the design by the section's ``tf_press_design``), stored with the cycle's comparison (``sections``);
4. the correction of every section, the single-piece loop's one correction (:func:`mppf.correct.step.correct_step`)
   on the section's plane-free deviations of every cycle (:class:`SectionHistory`, :func:`section_shapes`);
5. :func:`mppf.planning.sectional.apply_section_corrections`: the next cycle's job (one correction of the whole
   plate, not blended); one history cycle for all sections; the verdict is the whole plate's.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np

from mppf.core.presslink import PressLink
from mppf.core.progress import Reporter
from mppf.correct.verdict import Verdict
from mppf.loop.correcting import corrected_plate
from mppf.loop.history import History
from mppf.loop.pressing import close_cut_step, press_step
from mppf.loop.records import CycleRecord, PlateRecord, load_cycle_job
from mppf.loop.section_steps import cycle_steps, section_of_step, section_spans
from mppf.loop.settings import LoopSettings
from mppf.loop.states import CycleState, Decision
from mppf.model.job import Job
from mppf.model.job_parts import grid_from_json, grid_to_json
from mppf.model.job_provenance import LoopProvenance
from mppf.model.press import PressConfig
from mppf.planning.job import save_job
from mppf.planning.sectional import apply_section_corrections
from mppf.planning.sections import placement_text

#: Called before the steps of each section: ``place(section, previous)`` (previous None for the first section
#: pressed in this run); it tells the operator where the plate goes and, on a real press, waits for the
#: confirmation (raising PressRefused when it is not given).
PlaceCallback = Callable[[object, object], None]


def report_placement(reporter: Reporter) -> PlaceCallback:
    """The ``place`` of a simulated press: the placement line is reported and the loop goes on."""
    def place(section, previous) -> None:
        reporter.info(placement_text(section, previous))
    return place


# -- 1. pressing ----------------------------------------------------------------------------


def press_sections(history: History, record: CycleRecord, press: PressConfig, link: PressLink, reporter: Reporter,
                   job: Job, place: PlaceCallback) -> None:
    """Press every step of the cycle not yet started, section by section; the cycle ends "pressed".

    A cycle found in "pressing" (a crash) goes on from the first step not started: a step cut short
    is closed unfinished (:func:`mppf.loop.pressing.close_cut_step`) and not pressed again; the cycle
    is then recorded interrupted. ``place`` is called before the first step pressed in this run and
    at every change of section.

    Raises
    ------
    PressRefused
        The operator did not confirm a placement (nothing of that section was sent), or the press
        refused a step before any motion (recorded as not started).
    InputError, LinkError, PlcError, PressFault, Cancelled
        As :func:`mppf.loop.pressing.press_step`.
    """
    resumed = record.state == CycleState.PRESSING
    record = close_cut_step(history, record, press)
    link.job_sha256 = record.job_sha256  # the press driver writes it into the audit log
    spans = {k: (first, last) for k, first, last in section_spans(job)}
    placed = None
    for index in range(record.steps_done + 1, len(record.steps) + 1):
        k = section_of_step(job, index)
        if placed != k:
            place(job.sections[k - 1], None if placed is None else job.sections[placed - 1])
            placed = k
        first, last = spans[k]
        press_step(history, record, press, link, reporter, index,
                   f"(section {k} of {len(job.sections)}, step {index - first + 1} of {last - first + 1})")
        record = history.cycle(record.plate_id, record.cycle)
    history.mark_pressed(record.plate_id, record.cycle, interrupted=resumed,
                         detail="resumed: the steps not started were pressed" if resumed else "")


# -- 3. the deviations at every section's punches ---------------------------------------------


def section_deviations(comparison, design_points, job: Job) -> list[dict]:
    """The deviation at every section's punches, from one comparison of the whole plate.

    The punch axes of section k are taken to the design by its ``tf_press_design``
    (:func:`mppf.measure.punches.punch_deviations` on the comparison's measured points; the same
    design skin as :func:`mppf.measure.compare.compare`'s).

    Parameters
    ----------
    comparison : Comparison
        Of the scan of the whole plate with the whole design.
    design_points : (m, 3) float, mm
    job : Job
        A sectional job.

    Returns
    -------
    list of dict
        Per section, in pressing order: ``index``, ``punch_deviation_mm`` (rows x cols, JSON: null
        where the punch is off the plate), ``interpolated`` (punches filled across scan gaps).
    """
    from mppf.geometry.surface import fit_plate
    from mppf.measure.deviations import DesignSkin
    from mppf.measure.punches import punch_deviations

    fitted = fit_plate(np.asarray(design_points, dtype=float), kind="spline", source="design")
    skin = DesignSkin(fitted, design_points, comparison.normal_sign, comparison.offset_mm, comparison.margin_mm)
    dev = skin.deviate(comparison.measured_in_design, np.eye(4))
    use = ~dev.outside & ~np.asarray(comparison.is_outlier, dtype=bool)
    x, y = np.meshgrid(job.punch_x_mm, job.punch_y_mm)
    punch_xy = np.stack([x, y], axis=-1)
    out = []
    for s in job.sections:
        along_z, _, interpolated = punch_deviations(punch_xy, s.tf_press_design, skin, dev, use, design_points)
        out.append({"index": s.index, "punch_deviation_mm": grid_to_json(along_z),
                    "interpolated": int(np.sum(interpolated))})
    return out


# -- 4. the correction of every section -------------------------------------------------------


def section_record(record: CycleRecord, job: Job, index: int) -> CycleRecord:
    """The cycle as section ``index`` saw it: its steps, their read-backs and counters, its punch deviations and
    the correction that made its strokes."""
    first, last = next((f, la) for k, f, la in section_spans(job) if k == index)
    n = last - first + 1

    def local(count: int) -> int:
        return int(min(max(count - (first - 1), 0), n))

    done = local(record.steps_done)
    deviation = None
    for s in (record.comparison or {}).get("sections", []):
        if s["index"] == index:
            deviation = grid_from_json(s["punch_deviation_mm"])
    correction = record.correction
    for c in (record.correction or {}).get("sections", []):
        if c.get("section") == index:
            correction = c
    return dataclasses.replace(record, steps=list(record.steps[first - 1:last]),
                               results=list(record.results[first - 1:first - 1 + done]),
                               step_started=local(record.step_started), steps_done=done,
                               punch_deviation_mm=deviation, correction=correction)


class SectionHistory:
    """The plate's history as section ``index`` saw it: every cycle through :func:`section_record`.

    Gives what the single-piece correction reads (:meth:`cycle`, :meth:`cycles`), so it corrects one
    section on the strokes and deviations of that section in every cycle.
    """

    def __init__(self, history: History, index: int):
        self.history, self.index, self._jobs = history, int(index), {}

    def _view(self, record: CycleRecord) -> CycleRecord:
        if record.job_sha256 not in self._jobs:
            self._jobs[record.job_sha256] = load_cycle_job(record)
        return section_record(record, self._jobs[record.job_sha256], self.index)

    def cycle(self, plate_id: str, cycle: int) -> CycleRecord:
        return self._view(self.history.cycle(plate_id, cycle))

    def cycles(self, plate_id: str) -> list[CycleRecord]:
        return [self._view(r) for r in self.history.cycles(plate_id)]


def plan_next_sections(history: History, plate: PlateRecord, record: CycleRecord, press: PressConfig,
                       settings: LoopSettings) -> Verdict | None:
    """Correct every section by its measured deviations and record the next cycle ("planned"), or stop.

    Every section gets the single plate's correction (:func:`mppf.correct.step.correct_step`: its memory of every
    cycle, its step policy) on its **plane-free** deviation (:func:`section_shapes`: the deviation at its
    punches without its best plane, which is the section's pose, not its shape), with the whole plate's form
    max and RMS as the outcomes; the corrections are one correction of the whole plate and are not blended
    (:func:`mppf.planning.sectional.apply_section_corrections` with ``blend=False``). When a section's
    correction finds no way on (its verdict: cannot converge, strokes beyond the limits...), the loop stops
    with that verdict: the sections form one plate, and the others' corrections alone would throw it.
    The new steps go from flat, validated; the compared cycle moves to "corrected" in the same
    transaction.

    Returns
    -------
    Verdict or None
        The first section's verdict when a section cannot be corrected (nothing recorded), else None.

    Raises
    ------
    LimitError
        Corrected strokes the press cannot take.
    """
    job = load_cycle_job(record)
    deltas, corrections, verdicts = _learned_sections(history, plate, record, press, settings, job)
    if verdicts:  # the sections form one plate: one that cannot go on stops it
        return verdicts[0]
    corrected = apply_section_corrections(job, deltas, blend=False)
    loop = LoopProvenance(plate_id=plate.plate_id, cycle=record.cycle + 1, corrects_job_sha256=record.job_sha256)
    corrected = dataclasses.replace(corrected, loop=loop, seal=None)
    path = save_job(corrected, Path(plate.settings["work_dir"]) / f"cycle-{record.cycle + 1:02d}.job.json")
    history.add_cycle(
        plate.plate_id, record.cycle + 1, job_path=path.resolve(), job_sha256=corrected.sha256(),
        steps=cycle_steps(corrected), gain=_mean_gain(corrections),
        correction={"strategy": "sections-learned", "sections": corrections},
        previous_decision=Decision.CONTINUE,
    )
    return None


def _learned_sections(history, plate, record, press, settings, job) -> tuple[list, list, list]:
    """Per section the learned correction's change of its final strokes, its record, and the verdicts."""
    from mppf.correct.inputs import CorrectionHistory
    from mppf.correct.policy import DEFAULT_NOISE_MM
    from mppf.correct.step import Tolerances, correct_step, outcome
    from mppf.loop.correcting import pressed_cycle, step_to_dict

    noise = ((record.comparison or {}).get("form") or {}).get("noise_mm") or DEFAULT_NOISE_MM
    tolerances = Tolerances(settings.tolerance_mm, settings.rms_tolerance_mm, float(noise))
    deltas, corrections, verdicts = [], [], []
    for s in job.sections:
        view = SectionHistory(history, s.index)
        records = [r for r in view.cycles(record.plate_id)[: record.cycle] if r.punch_deviation_mm is not None
                   and r.rms_mm is not None]
        cycles, outcomes, strokes = [], [], []
        for r in records:
            shape = section_shapes(press, [r.steps[-1].active], [r.punch_deviation_mm])[0]
            cycle = pressed_cycle(r, press)
            if cycle.steps_mid_mm:
                cycles.append(dataclasses.replace(cycle, error_mm=shape))
            promised = (r.correction or {}).get("predicted_mm")
            outcomes.append(outcome(r.max_abs_mm, r.rms_mm, shape,
                                    None if promised is None else grid_from_json(promised)))
            strokes.append((r.steps[-1].upper_mm, r.steps[-1].lower_mm))
        final = s.steps[-1]
        corrected = corrected_plate(s.layout, plate, press, final.active)
        step = correct_step(corrected, CorrectionHistory(cycles, outcomes, strokes), tolerances)
        if step.verdict is not None:
            verdicts.append(step.verdict)
            deltas.append((np.zeros(press.shape), np.zeros(press.shape)))
            corrections.append({"section": s.index, "verdict": step.verdict.text})
            continue
        deltas.append((np.where(final.active, step.learned.upper_mm - final.upper_mm, 0.0),
                       np.where(final.active, step.learned.lower_mm - final.lower_mm, 0.0)))
        corrections.append({"section": s.index, **step_to_dict(step), "gain": grid_to_json(
            np.where(final.active, float(np.mean(step.learned.gains)) if step.learned.gains.size else 1.0, np.nan))})
    return deltas, corrections, verdicts


def section_shapes(press: PressConfig, actives, deviations) -> list[np.ndarray]:
    """Per section, (rows, cols) mm: its deviation at its active punches without its best plane (its pose).

    ``actives``: each section's active punches; ``deviations``: its deviation at its punches (NaN unknown).
    """
    from mppf.core.grid import without_plane

    gx, gy = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    out = []
    for active, dev in zip(actives, deviations):
        dev = np.asarray(dev, dtype=float)
        known = np.asarray(active, dtype=bool) & np.isfinite(dev)
        out.append(np.where(known, without_plane(gx, gy, np.where(known, dev, 0.0), known), np.nan))
    return out


def _mean_gain(corrections: list) -> float | None:
    """The mean gain of the sections' corrections over their punches (None when no punch has one)."""
    values = [v for c in corrections if c.get("gain") is not None
              for v in np.ravel(np.asarray(grid_from_json(c["gain"]), dtype=float))]
    values = [v for v in values if np.isfinite(v)]
    return float(np.mean(values)) if values else None
