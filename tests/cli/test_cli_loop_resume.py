"""Crash safety: kill -9 of ``mppf loop`` mid-cycle, then ``mppf loop --resume``.

The loop runs as a real subprocess (with its simulated PLC in-process, real Modbus over
loopback) on a plate recorded from the session's planned job; the test watches the history
database, kills the process the moment a cycle is recorded as "pressing" (motion slowed so
that the kill lands during the motion), and resumes. Nothing may be lost and no cycle may be
pressed twice: checked in the history and in the audit log's GO commands per cycle (job hash)
and per sequence number.
"""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from mppf.loop.history import History
from mppf.loop.options import LoopOptions, PlateInputs
from mppf.loop.plate import record_plate
from mppf.loop.settings import LoopSettings


def _mppf(*args) -> list[str]:
    return [sys.executable, "-m", "mppf", *args]


def _state(db: Path, plate_id: str) -> tuple[str, int] | None:
    """(state, cycle) of the plate's latest cycle, read without disturbing the writer."""
    if not db.exists():
        return None
    try:
        con = sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=1.0)
        try:
            row = con.execute("SELECT state, cycle FROM cycles WHERE plate_id = ? ORDER BY cycle DESC LIMIT 1",
                              (plate_id,)).fetchone()
        finally:
            con.close()
    except sqlite3.OperationalError:  # tables not created yet
        return None
    return row


# minutes of simulation: real processes, motion at 4x real speed until the kill, then two cycles of the
# steel-plate simulator (the resume logic itself is tested in-process: tests/loop/test_cycle.py)
@pytest.mark.slow
def test_kill_while_pressing_then_resume_loses_nothing_and_presses_nothing_twice(planned_plate, tmp_path):
    env = {**os.environ, "MPPF_HOME": str(tmp_path / "home")}
    db = tmp_path / "home" / "history.sqlite"
    design, flat, press, job = planned_plate
    # the plate as 'mppf loop DESIGN FLAT --plate-id K2-crash --seed 3 --max-cycles 2' records it
    with History(db) as history:
        record_plate(history, PlateInputs(design, flat, press, 20.0), job, plate_id="K2-crash",
                     work_dir=tmp_path / "home" / "plates" / "K2-crash",
                     options=LoopOptions(settings=LoopSettings(max_cycles=2),
                                         setup={"plc": None, "scanner": "sim", "seed": 3, "units": "mm",
                                                "material": "steel"}))
    # slow motion (4x real speed): the first press step takes seconds
    args = _mppf("loop", "--resume", "--plate-id", "K2-crash", "--time-scale", "4")
    err = tmp_path / "loop.err"
    with err.open("wb") as err_file:
        proc = subprocess.Popen(args, env=env, stdout=subprocess.DEVNULL, stderr=err_file)
    try:
        deadline = time.monotonic() + 120
        while _state(db, "K2-crash") != ("pressing", 1):
            assert proc.poll() is None, err.read_text()
            assert time.monotonic() < deadline, "the loop never started pressing"
            time.sleep(0.02)
        time.sleep(0.5)  # well inside the motion
        os.kill(proc.pid, signal.SIGKILL)  # a crash / power cut of the master
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == -signal.SIGKILL
    with History(db) as history:
        killed = history.cycle("K2-crash", 1)
    assert killed.state == "pressing" and killed.steps_done < killed.step_started
    audit_db = tmp_path / "home" / "audit.sqlite"
    gos_before = _gos(audit_db)

    # resume: fast motion now; it must measure cycle 1, not press it again
    done = subprocess.run(_mppf("loop", "--resume", "--time-scale", "200", "--json"), env=env,
                          capture_output=True, text=True, timeout=300)
    doc = json.loads(done.stdout)
    assert doc["plate_id"] == "K2-crash" and doc["resumed_state"] == "pressing"
    assert doc["status"] in ("in_tolerance", "max_cycles", "diverged")  # the loop ran to its end
    # the documented exit code of its ending: 0 in tolerance, 5 ended out of tolerance
    assert done.returncode == (0 if doc["status"] == "in_tolerance" else 5), done.stderr

    with History(db) as history:
        cycles = history.cycles("K2-crash")
        events = history.events("K2-crash")
    first = cycles[0]
    # cycle 1: nothing lost (its strokes, the step that was running), recorded as interrupted, measured
    assert first.interrupted and first.step_started == killed.step_started
    assert first.steps_done == killed.steps_done
    assert first.scan_sha256 and first.max_abs_mm is not None and first.state == "corrected"
    for got, before in zip(first.steps, killed.steps, strict=True):
        np.testing.assert_array_equal(got.lower_mm, before.lower_mm)
        np.testing.assert_array_equal(got.upper_mm, before.upper_mm)
    # the cycle entered "pressing" exactly once, every later cycle too
    for c in cycles:
        pressing = [e for e in events if e.cycle == c.cycle and e.state == "pressing" and e.detail == "step 1 started"]
        assert len(pressing) == 1
    # the audit log: GO for cycle 1 only before the crash, one GO per step of every later cycle
    gos_after = _gos(audit_db)
    assert gos_after.get(first.job_sha256, 0) == gos_before.get(first.job_sha256, 0) <= first.step_started
    for c in cycles[1:]:
        assert gos_after[c.job_sha256] == len(c.steps)
    # and no sequence number got two GOs from one process
    con = sqlite3.connect(audit_db)
    dupes = con.execute("SELECT pid, sequence, COUNT(*) FROM audit WHERE action = 'go' GROUP BY pid, sequence "
                        "HAVING COUNT(*) > 1").fetchall()
    assert dupes == []


def _gos(audit_db: Path) -> dict[str, int]:
    con = sqlite3.connect(audit_db)
    try:
        rows = con.execute("SELECT job_sha256, COUNT(*) FROM audit WHERE action = 'go' GROUP BY job_sha256").fetchall()
    finally:
        con.close()
    return dict(rows)
