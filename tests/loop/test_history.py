"""The SQLite plate history: states, atomic moves, refusal to press twice, listing."""

from __future__ import annotations

import json
import sqlite3

import numpy as np
import pytest

from mppf.cli import main
from mppf.core.errors import InputError
from mppf.loop.history import History, default_history_path
from mppf.loop.options import PlateFiles
from mppf.model.job_parts import StepStrokes
from mppf.model.press import example_press_path, load_press


@pytest.fixture()
def press():
    return load_press(example_press_path())


def _steps(press, depth_mm=10.0):
    active = np.zeros(press.shape, dtype=bool)
    active[2:10, 3:15] = True
    lower = np.where(active, depth_mm, np.nan)
    return [StepStrokes(upper_mm=lower + 20.0, lower_mm=lower, active=active)]


def _new(history, press, plate_id="P-1"):
    history.create_plate(plate_id, PlateFiles("/d.csv", "a" * 64, "/f.csv", "b" * 64), thickness_mm=20.0,
                         press=press.to_dict(), settings={"loop": {"tolerance_mm": 2.5}})
    history.add_cycle(plate_id, 1, job_path="/c1.json", job_sha256="c" * 64, steps=_steps(press))


def _through_compare(history, plate_id, cycle, max_abs_mm=4.0, decision="continue"):
    history.mark_step_started(plate_id, cycle, 1)
    history.mark_step_done(plate_id, cycle, 1, {"sequence": cycle, "max_error_mm": 0.05})
    history.mark_pressed(plate_id, cycle)
    history.mark_scanned(plate_id, cycle, f"/scan{cycle}.ply", "d" * 64)
    grid = np.full((16, 24), np.nan)
    grid[3, 4] = -1.25
    history.mark_compared(plate_id, cycle, rms_mm=1.5, max_abs_mm=max_abs_mm, within_pct=80.0,
                          punch_deviation_mm=grid, comparison={"rms_mm": 1.5}, decision=decision)


def test_cycle_goes_through_all_states_and_round_trips(tmp_path, press):
    with History(tmp_path / "h.sqlite") as history:
        _new(history, press)
        _through_compare(history, "P-1", 1)
        history.add_cycle("P-1", 2, job_path="/c2.json", job_sha256="e" * 64, steps=_steps(press, 12.0),
                          gain=0.8, correction={"gain": 0.8}, previous_decision="continue")
        _through_compare(history, "P-1", 2, max_abs_mm=1.0, decision="in_tolerance")
        history.mark_done("P-1", 2, "in_tolerance")
    # a fresh connection sees everything (committed)
    with History(tmp_path / "h.sqlite") as history:
        first, second = history.cycles("P-1")
        assert (first.state, second.state) == ("corrected", "done")
        assert history.plate("P-1").status == "in_tolerance"
        assert second.gain == 0.8 and second.correction == {"gain": 0.8}
        assert first.punch_deviation_mm[3, 4] == -1.25 and np.isnan(first.punch_deviation_mm[0, 0])
        np.testing.assert_array_equal(second.steps[0].active, _steps(press)[0].active)
        assert np.nanmax(second.steps[0].lower_mm) == 12.0
        states = [e.state for e in history.events("P-1") if e.cycle == 1]
        assert states == ["planned", "pressing", "pressing", "pressed", "scanned", "compared", "corrected"]


def test_database_is_wal(tmp_path, press):
    with History(tmp_path / "h.sqlite") as history:
        _new(history, press)
    db = sqlite3.connect(tmp_path / "h.sqlite")
    assert db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"


def test_a_cycle_cannot_start_pressing_twice(tmp_path, press):
    path = tmp_path / "h.sqlite"
    with History(path) as one, History(path) as two:
        _new(one, press)
        one.mark_step_started("P-1", 1, 1)
        # a second process (or a resume) must not start the same step again
        with pytest.raises(InputError, match="state 'pressing', step 1 started"):
            two.mark_step_started("P-1", 1, 1)
        # nor skip ahead before the step is done
        with pytest.raises(InputError):
            two.mark_step_started("P-1", 1, 2)


def test_out_of_order_moves_are_refused(tmp_path, press):
    with History(tmp_path / "h.sqlite") as history:
        _new(history, press)
        with pytest.raises(InputError, match="cannot move to 'scanned'"):
            history.mark_scanned("P-1", 1, "/s.ply", "0" * 64)
        with pytest.raises(InputError, match="state 'planned'"):
            history.mark_done("P-1", 1, "in_tolerance")
        assert history.cycle("P-1", 1).state == "planned"


def test_correcting_is_atomic_with_the_next_cycle(tmp_path, press):
    with History(tmp_path / "h.sqlite") as history:
        _new(history, press)
        _through_compare(history, "P-1", 1)
        # the next cycle already exists: the whole transaction fails, cycle 1 stays compared
        history.add_cycle("P-1", 2, job_path="/c2.json", job_sha256="e" * 64, steps=_steps(press))
        with pytest.raises(sqlite3.IntegrityError):
            history.add_cycle("P-1", 2, job_path="/c2.json", job_sha256="e" * 64, steps=_steps(press),
                              previous_decision="continue")
        assert history.cycle("P-1", 1).state == "compared"


def test_duplicate_and_unknown_plates(tmp_path, press):
    with History(tmp_path / "h.sqlite") as history:
        _new(history, press)
        with pytest.raises(InputError, match="already in the history"):
            _new(history, press)
        with pytest.raises(InputError, match="known plates: P-1"):
            history.plate("nope")


def test_not_a_database_is_an_input_error(tmp_path):
    bad = tmp_path / "bad.sqlite"
    bad.write_text("this is not sqlite " * 100)
    with pytest.raises(InputError, match="cannot open the plate history"):
        History(bad)


def test_default_path_follows_mppf_home(tmp_path, monkeypatch):
    monkeypatch.setenv("MPPF_HOME", str(tmp_path))
    assert default_history_path() == tmp_path / "history.sqlite"


def test_history_command_lists_plates_and_cycles(tmp_path, press, capsys):
    path = tmp_path / "h.sqlite"
    with History(path) as history:
        _new(history, press, "PLATE-A")
        _through_compare(history, "PLATE-A", 1, max_abs_mm=3.5)
        _new(history, press, "PLATE-B")
    assert main(["history", "--history", str(path)]) == 0
    out = capsys.readouterr().out
    assert "PLATE-A" in out and "PLATE-B" in out
    assert main(["history", "--history", str(path), "--plate-id", "PLATE-A", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["plates"][0]["plate_id"] == "PLATE-A"
    cycle = doc["plates"][0]["cycles"][0]
    assert cycle["state"] == "compared" and cycle["max_abs_mm"] == 3.5
    assert cycle["punch_deviation_mm"][3][4] == -1.25
    assert main(["history", "--history", str(path), "--plate-id", "nope"]) == 2
    assert "not in the history" in capsys.readouterr().err


def test_states_are_stored_as_their_text_and_read_back_as_enums(tmp_path, press):
    from mppf.loop.states import CycleState, Decision, PlateStatus

    path = tmp_path / "h.sqlite"
    with History(path) as history:
        _new(history, press)
        _through_compare(history, "P-1", 1, decision="in_tolerance")
        history.mark_done("P-1", 1, Decision.IN_TOLERANCE)
    raw = sqlite3.connect(path)
    assert raw.execute("SELECT state, typeof(state), decision FROM cycles").fetchall() == [
        ("done", "text", "in_tolerance")]
    assert raw.execute("SELECT status FROM plates").fetchall() == [("in_tolerance",)]
    with History(path) as history:  # what an earlier mppf wrote reads the same
        cycle, plate = history.cycle("P-1", 1), history.plate("P-1")
    assert cycle.state is CycleState.DONE and cycle.decision is Decision.IN_TOLERANCE
    assert plate.status is PlateStatus.IN_TOLERANCE and plate.status == "in_tolerance"
    assert json.loads(json.dumps(cycle.to_dict(grids=False)))["state"] == "done"
