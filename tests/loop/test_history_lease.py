"""One loop per plate and atomic state changes: the history's lease, one-transaction recording, full disks.

The lease is tried with real processes: a child holds it, a second taker is refused with
the holder named, a killed holder's lease is taken over; two ``mppf loop --resume`` on one
plate, the second refused. A full disk is simulated with SQLite's ``max_page_count``.
"""

from __future__ import annotations

import os
import signal
import socket
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mppf.cli import main
from mppf.core.db import open_sqlite
from mppf.core.errors import InputError
from mppf.loop import lease as leases
from mppf.loop.history import History
from mppf.loop.options import LoopOptions, PlateFiles, PlateInputs
from mppf.loop.plate import record_plate
from mppf.loop.settings import LoopSettings

HOLDER = """
import sys, time
from mppf.loop.history import History
with History(sys.argv[1]) as history, history.lease(sys.argv[2]):
    print("held", flush=True)
    time.sleep(120)
"""


def _record(tmp_path: Path, planned_plate, plate_id: str) -> Path:
    design, flat, press, job = planned_plate
    with History(tmp_path / "history.sqlite") as history:
        record_plate(history, PlateInputs(design, flat, press, 20.0), job, plate_id=plate_id,
                     work_dir=tmp_path / plate_id,
                     options=LoopOptions(settings=LoopSettings(max_cycles=1), setup={"scanner": "sim", "seed": 1}))
    return tmp_path / "history.sqlite"


def _holder(db: Path, plate_id: str) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-c", HOLDER, str(db), plate_id], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "held"
    return proc


def test_a_held_lease_refuses_a_second_process_naming_the_owner_and_a_killed_one_is_taken_over(tmp_path):
    db = tmp_path / "history.sqlite"
    proc = _holder(db, "B12-P3")
    try:
        with History(db) as history:
            with pytest.raises(InputError) as refused:
                with history.lease("B12-P3"):
                    pass
            assert f"pid {proc.pid}" in refused.value.message and socket.gethostname() in refused.value.message
            assert "another mppf loop" in refused.value.message
            assert history.current_lease("B12-P3").pid == proc.pid  # the refusal took nothing
            proc.send_signal(signal.SIGKILL)
            proc.communicate(timeout=10)
            with history.lease("B12-P3") as taken_over:
                assert f"process {proc.pid} has ended" in taken_over
                assert history.current_lease("B12-P3").pid == os.getpid()
            assert history.current_lease("B12-P3") is None  # given back after the block
    finally:
        proc.kill()
        proc.communicate(timeout=10)


def test_a_lease_is_taken_over_only_after_its_heartbeat_expired(tmp_path):
    with History(tmp_path / "history.sqlite") as history:
        db = history._db
        now = time.time()
        db.execute("INSERT INTO leases VALUES ('P1', 'alice', 'other-host', 4242, 't', ?, ?)", (now - 100, now - 2))
        with pytest.raises(InputError, match="alice on host other-host, pid 4242"):
            with history.lease("P1"):
                pass
        db.execute("UPDATE leases SET heartbeat_s = ?", (now - leases.LEASE_EXPIRY_S - 5,))
        with history.lease("P1") as taken_over:
            assert "heartbeat expired" in taken_over and "alice" in taken_over


def test_the_holder_renews_its_heartbeat_and_stops_when_taken_over(tmp_path):
    path = tmp_path / "history.sqlite"
    with History(path) as history:
        mine, _ = leases.take_lease(history._db, history.transaction, "P2")

        def connect():
            return open_sqlite(path, "history", "", 1, hint="")

        with leases.heartbeat(connect, mine, every_s=0.05):
            time.sleep(0.4)
            renewed = history.current_lease("P2").heartbeat_s
        assert renewed > mine.heartbeat_s
        history._db.execute("UPDATE leases SET token = 'someone else'")
        assert not leases.renew_lease(history._db, mine)


def test_a_plate_and_its_first_cycle_are_recorded_together_or_not_at_all(planned_plate, tmp_path, monkeypatch):
    design, flat, press, job = planned_plate

    def crash(*args, **kwargs):
        raise OSError("power cut between the plate and its first cycle")

    with History(tmp_path / "history.sqlite") as history:
        monkeypatch.setattr(History, "add_cycle", crash)
        with pytest.raises(OSError):
            record_plate(history, PlateInputs(design, flat, press, 20.0), job, plate_id="A1", work_dir=tmp_path / "A1")
        assert history.plates() == []  # neither the plate nor its cycle
        monkeypatch.undo()
        record_plate(history, PlateInputs(design, flat, press, 20.0), job, plate_id="A1", work_dir=tmp_path / "A1")
        assert [c.state for c in history.cycles("A1")] == ["planned"]


def test_a_plate_left_without_cycles_by_an_older_mppf_can_be_started_again(planned_plate, tmp_path):
    design, flat, press, job = planned_plate
    with History(tmp_path / "history.sqlite") as history:
        history.create_plate("OLD-1", PlateFiles(design.path, design.sha256, flat.path, flat.sha256), thickness_mm=20.0,
                             press=press.to_dict(), settings={})
        record_plate(history, PlateInputs(design, flat, press, 20.0), job, plate_id="OLD-1",
                     work_dir=tmp_path / "OLD-1")
        assert len(history.cycles("OLD-1")) == 1
        with pytest.raises(InputError, match="already in the history"):
            history.check_new_plate("OLD-1")


@pytest.mark.parametrize("plate_id", ["../../../x", "B12[/]P3", "a/b", "", ".hidden", "x" * 65, "a b", "P..1"])
def test_unsafe_plate_ids_are_refused(tmp_path, plate_id):
    with History(tmp_path / "history.sqlite") as history, pytest.raises(InputError, match="is not allowed"):
        history.check_new_plate(plate_id)


def test_interrupted_only_when_a_step_was_really_cut_short(planned_plate, tmp_path):
    design, flat, press, job = planned_plate
    with History(tmp_path / "history.sqlite") as history:
        for plate_id, finished in (("DONE-1", True), ("CUT-1", False)):
            record_plate(history, PlateInputs(design, flat, press, 20.0), job, plate_id=plate_id,
                         work_dir=tmp_path / plate_id)
            steps = len(job.steps) if finished else 1
            for step in range(1, steps + 1):
                history.mark_step_started(plate_id, 1, step)
                if finished:
                    history.mark_step_done(plate_id, 1, step, {"max_error_mm": 0.1})
            history.mark_pressed(plate_id, 1, interrupted=True, detail="resumed after a kill")  # what resume does
        assert not history.cycle("DONE-1", 1).interrupted  # killed after the last step was recorded done
        assert history.cycle("CUT-1", 1).interrupted


def _full_disk(monkeypatch):
    """Every history opened from now on may not grow: SQLite reports 'database or disk is full'."""
    import mppf.loop.history as history_module

    def full(*args, **kwargs):
        db = open_sqlite(*args, **kwargs)
        pages = db.execute("PRAGMA page_count").fetchone()[0]
        db.execute(f"PRAGMA max_page_count = {pages}")
        return db

    monkeypatch.setattr(history_module, "open_sqlite", full)


def test_a_full_disk_is_a_clear_error_and_leaves_the_state_as_it_was(planned_plate, tmp_path, monkeypatch):
    db = _record(tmp_path, planned_plate, "FULL-1")
    _full_disk(monkeypatch)
    with History(db) as history:
        big = "x" * 200_000
        with pytest.raises(InputError, match="the disk is full") as full:
            with history.transaction():
                history._db.execute("UPDATE plates SET note = ? WHERE plate_id = 'FULL-1'", (big,))
        assert "mppf loop --resume" in full.value.hint
        assert history.plate("FULL-1").note == "" and history.cycle("FULL-1", 1).state == "planned"


def test_mppf_loop_on_a_full_disk_exits_2_and_the_plate_resumes_later(planned_plate, tmp_path, monkeypatch, capsys):
    db = _record(tmp_path, planned_plate, "FULL-2")
    with sqlite3.connect(db) as con:  # fill the last page: the lease's row no longer fits
        con.execute("UPDATE plates SET note = ? WHERE plate_id = 'FULL-2'", ("n" * 3000,))
    _full_disk(monkeypatch)
    code = main(["loop", "--resume", "--plate-id", "FULL-2", "--history", str(db)])
    err = " ".join(capsys.readouterr().err.split())
    assert code == 2, err
    assert "cannot write the plate history" in err and "Traceback" not in err and "internal error" not in err
    monkeypatch.undo()
    with History(db) as history:
        assert history.plate("FULL-2").status == "active" and history.cycle("FULL-2", 1).state == "planned"
        assert history.current_lease("FULL-2") is None


def _wait_for_lease(db: Path, plate_id: str, proc: subprocess.Popen, timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            con = sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=1.0)
            try:
                if con.execute("SELECT 1 FROM leases WHERE plate_id = ?", (plate_id,)).fetchone():
                    return
            finally:
                con.close()
        except sqlite3.OperationalError:
            pass
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the first mppf loop took no lease"
        time.sleep(0.05)


def test_two_loops_on_one_plate_the_second_is_refused_and_a_killed_ones_lease_is_taken_over(planned_plate, tmp_path):
    db = _record(tmp_path, planned_plate, "RACE-1")
    env = {**os.environ, "MPPF_HOME": str(tmp_path / "home")}
    args = [sys.executable, "-m", "mppf", "loop", "--resume", "--plate-id", "RACE-1", "--history", str(db),
            "--time-scale", "1"]
    first = subprocess.Popen(args, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        _wait_for_lease(db, "RACE-1", first)
        second = subprocess.run(args, env=env, capture_output=True, text=True, timeout=60)
        err = " ".join(second.stderr.split())
        assert second.returncode == 2, err
        assert "is being run by another mppf loop" in err and f"pid {first.pid}" in err and "Traceback" not in err
        first.send_signal(signal.SIGKILL)
        first.wait(timeout=10)
        third = subprocess.Popen(args, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        try:
            line, deadline = "", time.monotonic() + 60
            while "took over the stale lease" not in line:
                line = third.stderr.readline()
                assert line or third.poll() is None, third.communicate()
                assert time.monotonic() < deadline
            assert f"process {first.pid} has ended" in line
        finally:
            third.send_signal(signal.SIGTERM)
            third.communicate(timeout=30)
    finally:
        first.kill()
        first.communicate(timeout=10)
    with History(db) as history:
        assert history.current_lease("RACE-1") is None  # the third gave it back when stopped


def test_a_plate_without_cycles_says_how_to_restart_it_and_then_restarts(planned_plate, tmp_path, capsys):
    design, flat, press, _ = planned_plate
    db = tmp_path / "history.sqlite"
    with History(db) as history:  # what an older mppf left when killed between the plate and its cycle
        history.create_plate("HALF-1", PlateFiles(design.path, design.sha256, flat.path, flat.sha256),
                             thickness_mm=20.0, press=press.to_dict(), settings={})
    assert main(["loop", "--resume", "--plate-id", "HALF-1", "--history", str(db)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "recorded without its first cycle" in err and "--plate-id HALF-1" in err
    with History(db) as history:
        history.check_new_plate("HALF-1")  # may be started again under its id
