"""The loop presses only what its sealed job holds: the history's copy of the strokes is checked against it."""

from __future__ import annotations

import json
import sqlite3

import pytest

from mppf.core.errors import ConfigError
from mppf.loop.history import History
from mppf.loop.options import LoopOptions, PlateInputs
from mppf.loop.plate import record_plate
from mppf.loop.pressing import check_step_is_sealed
from mppf.loop.settings import LoopSettings


def _recorded(tmp_path, planned_plate):
    design, flat, press, job = planned_plate
    history = History(tmp_path / "h.sqlite")
    record_plate(history, PlateInputs(design, flat, press, 20.0), job, plate_id="S1", work_dir=tmp_path / "S1",
                 options=LoopOptions(settings=LoopSettings(max_cycles=1)))
    return history


def test_a_recorded_cycle_matches_its_sealed_job(planned_plate, tmp_path):
    with _recorded(tmp_path, planned_plate) as history:
        record = history.cycle("S1", 1)
        for index in range(1, len(record.steps) + 1):
            check_step_is_sealed(record, index)


def test_strokes_edited_in_the_history_are_refused(planned_plate, tmp_path):
    with _recorded(tmp_path, planned_plate) as history:
        pass
    with sqlite3.connect(tmp_path / "h.sqlite") as con:  # the history edited behind mppf's back
        (text,) = con.execute("SELECT steps_json FROM cycles WHERE plate_id = 'S1' AND cycle = 1").fetchone()
        steps = json.loads(text)
        row = next(r for r in steps[0]["upper_mm"] if any(v is not None for v in r))
        row[next(i for i, v in enumerate(row) if v is not None)] += 2.0
        con.execute("UPDATE cycles SET steps_json = ? WHERE plate_id = 'S1' AND cycle = 1", (json.dumps(steps),))
    with History(tmp_path / "h.sqlite") as history:
        record = history.cycle("S1", 1)
        with pytest.raises(ConfigError, match="step 1 in the history is not step 1 of its sealed job"):
            check_step_is_sealed(record, 1)


def test_a_job_file_edited_after_it_was_recorded_is_refused(planned_plate, tmp_path):
    with _recorded(tmp_path, planned_plate) as history:
        record = history.cycle("S1", 1)
    path = tmp_path / "S1" / "cycle-01.job.json"
    doc = json.loads(path.read_text())
    doc["thickness_mm"] = 19.0
    path.write_text(json.dumps(doc, indent=1))
    with pytest.raises(ConfigError, match="changed after it was sealed.*changed: thickness"):
        check_step_is_sealed(record, 1)


def test_a_press_that_is_not_the_jobs_is_refused(planned_plate, tmp_path):
    from driver_helpers import small_press

    with _recorded(tmp_path, planned_plate) as history:
        record = history.cycle("S1", 1)
    check_step_is_sealed(record, 1, planned_plate[2])
    with pytest.raises(ConfigError, match="the press recorded in the history is not the press of its sealed job"):
        check_step_is_sealed(record, 1, small_press())
