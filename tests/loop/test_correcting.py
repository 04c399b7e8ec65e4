"""The loop's learned correction: what a cycle tells it (every step the press did, an interrupted one
last), the next cycle it records, and the stop with a verdict when it finds no way on."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import mppf.correct.step
from mppf.core.errors import EXIT_INPUT, InputError
from mppf.correct.inputs import CorrectedPlate, CorrectionHistory
from mppf.correct.memory import PressedCycle
from mppf.correct.step import Tolerances, correct_step, outcome
from mppf.correct.verdict import Verdict
from mppf.loop.correcting import corrected_plate, pressed_cycle
from mppf.loop.cycle import run_loop
from mppf.loop.history import History
from mppf.loop.options import LoopOptions, PlateInputs
from mppf.loop.plate import record_plate
from mppf.loop.records import CycleRecord
from mppf.loop.settings import LoopSettings
from mppf.loop.states import CycleState, Decision
from mppf.model.job_parts import StepStrokes, grid_to_json
from mppf.model.material import MATERIALS
from mppf.model.press import example_press_path, load_press
from mppf.planning.job import load_job
from mppf.sim.plc.link import InProcessPress
from mppf.sim.shop import SimulatedPlateScanner


def _record(steps, results, step_started, steps_done, deviation=None):
    return CycleRecord(
        plate_id="P", cycle=2, state=CycleState.COMPARED, created_utc="2026-01-01T00:00:00+00:00",
        updated_utc="2026-01-01T00:00:00+00:00", job_path="j", job_sha256="s", steps=steps,
        step_started=step_started, steps_done=steps_done, results=results, interrupted=step_started > steps_done,
        scan_path=None, scan_sha256=None, rms_mm=None, max_abs_mm=None, within_pct=None,
        punch_deviation_mm=deviation, comparison=None, gain=None, correction=None, decision=None,
    )


def test_a_cycle_counts_with_its_read_back_steps_and_the_interrupted_one_last():
    press = load_press(example_press_path())
    active = np.zeros(press.shape, dtype=bool)
    active[2:6, 3:9] = True
    steps = [StepStrokes(np.where(active, 20.0 + 10 * k, np.nan), np.where(active, 10.0 * k, np.nan), active)
             for k in (1, 2, 3)]
    # step 1 done (read back 0.2 mm short), step 2 interrupted in its motion, step 3 never started
    back_upper = np.where(active, 29.8, press.upper.park_mm)
    back_lower = np.where(active, 9.8, press.lower.park_mm)
    results = [{"actual_upper_mm": grid_to_json(back_upper), "actual_lower_mm": grid_to_json(back_lower)}]
    deviation = np.where(active, 1.0, np.nan)
    cycle = pressed_cycle(_record(steps, results, step_started=2, steps_done=1, deviation=deviation), press)
    assert len(cycle.steps_mid_mm) == 2 and cycle.interrupted and cycle.measured
    np.testing.assert_allclose(cycle.steps_mid_mm[0][active], 19.8)  # the read-back, not the setpoints
    np.testing.assert_allclose(cycle.steps_mid_mm[1][active], 30.0)  # the interrupted step's setpoints
    assert np.isnan(cycle.steps_mid_mm[0][~active]).all()
    # a completed cycle is not interrupted; an unmeasured one has no error
    done = pressed_cycle(_record(steps[:1], results, step_started=1, steps_done=1), press)
    assert not done.interrupted and not done.measured and len(done.steps_mid_mm) == 1


# The correction's tests see the whole plate without stray returns (no rescans: they have their own tests), at a
# coarser point spacing than the scanner's default (the correction, not the scan, is under test here).
CLEAR_VIEW = {"occlusion_fraction": 0.0, "outlier_fraction": 0.0, "spacing_mm": 35.0}


def _plate(tmp_path, planned_plate, history, plate_id, max_cycles):
    design, flat, press, job = planned_plate
    record_plate(history, PlateInputs(design, flat, press, 20.0), job, plate_id=plate_id, work_dir=tmp_path / plate_id,
                 options=LoopOptions(settings=LoopSettings(max_cycles=max_cycles)))
    job = load_job(history.cycle(plate_id, 1).job_path)
    return press, SimulatedPlateScanner.for_job(press, 20.0, job, flat.points, seed=3, **CLEAR_VIEW)


def test_the_loop_corrects_with_what_it_learned_and_records_it(planned_plate, tmp_path):
    with History(tmp_path / "h.sqlite") as history:
        press, scanner = _plate(tmp_path, planned_plate, history, "L1", max_cycles=2)
        with InProcessPress(press) as link:
            result = run_loop(history, "L1", link, scanner)
    first, second = result.cycles[:2]
    assert first.state == "corrected" and second.correction["strategy"] == "learned"
    assert second.correction["predicted_rms_mm"] < first.rms_mm
    assert "calibrated" in second.correction["notes"][0]
    # the next cycle's steps end on the corrected strokes, every one within the dimpling limit
    assert len(second.steps) >= 1 and np.array_equal(second.steps[-1].active, first.steps[-1].active)
    assert second.rms_mm < first.rms_mm


def test_a_correction_that_finds_no_way_on_stops_the_plate_with_its_verdict(planned_plate, tmp_path, monkeypatch):
    verdict = Verdict("the strokes it needs lie beyond the press's stroke limits at 3 punches", "re-plan it")
    monkeypatch.setattr(mppf.correct.step, "convergence_verdict", lambda *a, **k: verdict)
    with History(tmp_path / "h.sqlite") as history:
        press, scanner = _plate(tmp_path, planned_plate, history, "V1", max_cycles=5)
        with InProcessPress(press) as link:
            result = run_loop(history, "V1", link, scanner)
        assert history.plate("V1").status == "cannot_converge"
    assert result.status == Decision.CANNOT_CONVERGE and len(result.cycles) == 1
    assert result.cycles[0].state == "done"
    assert "stroke limits" in result.verdict and "re-plan" in result.verdict
    # the ending: the correction's reason and advice, the figures, exit 5
    end = result.ending
    assert end.decision == "cannot_converge" and end.exit_code == 5 and end.advice == "re-plan it"
    assert verdict.reason in end.why and "cycle 1: form max" in end.why and end.region.startswith("largest form")


def _older(job, **layout):
    """``job`` as an older mppf wrote it: its plate layout without some of its fields, unsealed."""
    return dataclasses.replace(job, layout=dataclasses.replace(job.layout, **layout), seal=None)


def test_a_job_without_design_heights_is_refused_when_the_loop_starts(planned_plate, tmp_path):
    """The correction aims at the design's heights at the punches: a job without them (an older mppf's) is
    refused before anything is pressed, with what to do (exit 2), not when the first correction is due."""
    design, flat, press, job = planned_plate
    with History(tmp_path / "h.sqlite") as history:
        record_plate(history, PlateInputs(design, flat, press, 20.0), _older(job, design_mid_mm=None),
                     plate_id="O1", work_dir=tmp_path / "O1", options=LoopOptions(settings=LoopSettings(max_cycles=2)))
        scanner = SimulatedPlateScanner.for_job(press, 20.0, job, flat.points, seed=3, **CLEAR_VIEW)
        with InProcessPress(press) as link, pytest.raises(InputError, match="no design heights") as refused:
            run_loop(history, "O1", link, scanner)
        cycle = history.cycle("O1", 1)
        assert cycle.state == CycleState.PLANNED and cycle.step_started == 0  # nothing pressed
    assert refused.value.exit_code == EXIT_INPUT and "--plate-id" in refused.value.hint


def test_an_older_job_without_its_material_is_corrected_for_the_material_recorded_with_the_plate(
        planned_plate, tmp_path):
    design, flat, press, job = planned_plate
    with History(tmp_path / "h.sqlite") as history:
        plate = record_plate(history, PlateInputs(design, flat, press, 20.0), _older(job, material=None),
                             plate_id="M1", work_dir=tmp_path / "M1",
                             options=LoopOptions(settings=LoopSettings(max_cycles=2), setup={"material": "ah36"}))
        scanner = SimulatedPlateScanner.for_job(press, 20.0, job, flat.points, seed=3, **CLEAR_VIEW)
        with InProcessPress(press) as link:
            result = run_loop(history, "M1", link, scanner)
    active = job.steps[-1].active
    assert corrected_plate(_older(job, material=None).layout, plate, press, active).nominal == MATERIALS["ah36"]
    assert corrected_plate(job.layout, plate, press, active).nominal == job.layout.material  # the job's own first
    assert len(result.cycles) >= 2 and result.cycles[1].correction["strategy"] == "learned"


def test_cycles_that_pressed_other_punches_are_corrected_by_the_one_correction(planned_plate):
    """A cycle that pressed fewer punches than the last one (a punch set that changed) no longer turns the loop to
    another correction: :func:`mppf.correct.step.correct_step` counts it at the punches the last cycle pressed
    (the others filled from their neighbours) and corrects every one of those."""
    design, flat, press, job = planned_plate
    final = job.steps[-1]
    rows, cols = np.nonzero(final.active)
    fewer = final.active.copy()
    fewer[rows.min(), cols[rows == rows.min()].min()] = False  # the earlier cycle left one corner punch out
    px, _ = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    span = float(np.ptp(px[final.active]))
    mids = [np.where(fewer, 0.5 * (s.upper_mm + s.lower_mm), np.nan) for s in job.steps]
    error = np.where(fewer, 3.0 * ((px - px[final.active].mean()) / span) ** 2, np.nan)  # a bend left at the ends
    history = CorrectionHistory([PressedCycle(mids, error)], [outcome(3.0, 1.2, error)],
                                [(final.upper_mm, final.lower_mm)])
    plate = CorrectedPlate(press, job.layout.design_mid_mm, 20.0, job.layout.material, final.active)
    step = correct_step(plate, history, Tolerances(2.5, 1.0))
    assert step.verdict is None
    assert np.isfinite(step.learned.lower_mm[final.active]).all()  # the corner punch too
    assert np.abs(step.learned.change_mm[final.active]).max() > 0.1
    assert step.learned.predicted_rms_mm < 1.2


def test_after_an_interruption_the_next_corrections_start_from_what_was_pressed(planned_plate, tmp_path):
    from mppf.core.errors import PressFault

    with History(tmp_path / "h.sqlite") as history:
        press, scanner = _plate(tmp_path, planned_plate, history, "I1", max_cycles=3)
        with InProcessPress(press) as link:
            link.program.inject("overpressure", after_s=2.0)  # hydraulic fault in the first motion
            with pytest.raises(PressFault):
                run_loop(history, "I1", link, scanner)
            link.reset()
            result = run_loop(history, "I1", link, scanner)  # resume: measured as it is, then corrected
    first, second = result.cycles[:2]
    assert first.interrupted and (first.step_started, first.steps_done) == (1, 0)
    assert second.correction["strategy"] == "learned"  # the interrupted cycle feeds the learned correction
    assert second.rms_mm < 0.5 * first.rms_mm
    assert result.status != Decision.DIVERGED
