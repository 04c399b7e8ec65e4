"""The bend - measure - compare loop: decisions, scan folder, convergence on the simulated press, bad input."""

from __future__ import annotations

import json
import os
import sqlite3
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from mppf.cli import main
from mppf.core.errors import InputError
from mppf.loop.history import History
from mppf.geometry.io import read_points, write_points
from mppf.loop.cycle import LoopSettings, decide
from mppf.planning.press import example_press_path, load_press
from mppf.core.scanner import ScanContext
from mppf.loop.scanners import DirectoryScanner
from mppf.geometry.unfold import unfold

PLATE = "K2_fwd_bilge_convex"  # a weakly doubly curved KCS bilge plate: plans fast
CONVERGING_PLATE = "P1_midbody_bilge_smooth"  # the DTC midship bilge, the demo's plate


def _design_and_flat(folder: Path, hull_dir: Path, name: str) -> tuple[Path, Path]:
    design = hull_dir / f"{name}.csv"
    return design, write_points(folder / f"{name}.flat.csv", unfold(read_points(design).points).flat)


@pytest.fixture(scope="module")
def plate_files(tmp_path_factory, hull_dir):
    """The design of a real hull plate and its unfolded flat, as files."""
    return _design_and_flat(tmp_path_factory.mktemp("plate"), hull_dir, PLATE)


def loop_args(design, flat, home: Path, *extra) -> list[str]:
    return ["loop", str(design), str(flat), "--press", str(example_press_path()), "--thickness", "20",
            "--history", str(home / "history.sqlite"), "--time-scale", "200", *extra]


# -- decisions ---------------------------------------------------------------------------------


def test_decide_in_tolerance_needs_both_limits():
    s = LoopSettings(tolerance_mm=2.5, rms_tolerance_mm=1.0, max_cycles=5)
    assert decide([0.9], 2.4, 1, s) == "in_tolerance"
    assert decide([1.1], 2.4, 1, s) == "continue"  # RMS too large
    assert decide([0.9], 2.6, 1, s) == "continue"  # one place too far off


def test_decide_divergence_and_max_cycles():
    s = LoopSettings(max_cycles=4, divergence_factor=1.5)
    assert decide([2.0, 3.1], 9.0, 2, s) == "diverged"  # grew by more than 1.5x
    assert decide([2.0, 2.9], 9.0, 2, s) == "continue"
    assert decide([1.5, 1.7, 1.9], 9.0, 3, s) == "diverged"  # grew twice in a row
    assert decide([1.5, 1.55, 1.6], 9.0, 3, s) == "continue"  # within the noise margin
    assert decide([3.0, 2.0, 1.5, 1.2], 3.0, 4, s) == "max_cycles"


@pytest.mark.parametrize("kwargs", [{"tolerance_mm": 0}, {"rms_tolerance_mm": -1}, {"max_cycles": 0},
                                    {"divergence_factor": 1.0}, {"gain": float("nan")}])
def test_bad_loop_settings(kwargs):
    with pytest.raises(InputError):
        LoopSettings(**kwargs)


# -- the scan folder ---------------------------------------------------------------------------


def _context(tmp_path, since_s, used=()):
    grid = np.zeros((2, 2))
    return ScanContext(plate_id="P", work_dir=tmp_path, since_s=since_s, upper_mm=grid, lower_mm=grid,
                       active=grid.astype(bool), used_paths=tuple(str(p) for p in used))


def test_directory_scanner_takes_the_new_complete_file(tmp_path):
    folder = tmp_path / "scans"
    folder.mkdir()
    old = folder / "old.csv"
    old.write_text("0,0,0\n")
    os.utime(old, (time.time() - 3600, time.time() - 3600))  # from before the cycle
    used = folder / "used.csv"
    used.write_text("1,1,1\n")  # an earlier cycle's scan
    (folder / "notes.txt.bak").write_text("not a scan")
    scanner = DirectoryScanner(folder, timeout_s=10, poll_s=0.05)
    target = folder / "cycle2.ply"

    def operator_saves_scan():
        time.sleep(0.3)
        target.write_bytes(b"x" * 100)

    thread = threading.Thread(target=operator_saves_scan)
    thread.start()
    try:
        got = scanner.acquire(2, _context(tmp_path, time.time() - 1, used=[used]))
    finally:
        thread.join()
    assert got == target


def test_directory_scanner_times_out_with_a_clear_error(tmp_path):
    scanner = DirectoryScanner(tmp_path, timeout_s=0.2, poll_s=0.05)
    with pytest.raises(InputError, match="no new scan file appeared") as info:
        scanner.acquire(1, _context(tmp_path, time.time()))
    assert "--resume" in info.value.hint


def test_directory_scanner_needs_a_folder(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        DirectoryScanner(tmp_path / "missing")


# -- the loop on the simulated press -----------------------------------------------------------


def test_loop_converges_on_the_simulated_press(hull_dir, tmp_path, capsys):
    design, flat = _design_and_flat(tmp_path, hull_dir, CONVERGING_PLATE)
    # seed 2: a plate whose first cycle is out of tolerance (the loop has to correct it)
    code = main(loop_args(design, flat, tmp_path, "--plate-id", "P1-A", "--seed", "2", "--json"))
    out = capsys.readouterr().out
    assert code == 0, out
    doc = json.loads(out)
    assert doc["status"] == "in_tolerance"
    last = doc["cycles"][-1]
    assert last["max_abs_mm"] <= 2.5 and last["rms_mm"] <= 1.0 and last["state"] == "done"
    assert 2 <= len(doc["cycles"]) <= 3
    with History(tmp_path / "history.sqlite") as history:
        cycles = history.cycles("P1-A")
        # every cycle went through every state; strokes, scan and deviations are recorded
        for c in cycles:
            states = [e.state for e in history.events("P1-A") if e.cycle == c.cycle]
            assert states[:1] == ["planned"] and {"pressing", "pressed", "scanned", "compared"} <= set(states)
            assert c.steps_done == len(c.steps) and len(c.results) == len(c.steps)
            assert Path(c.scan_path).exists() and len(c.scan_sha256) == 64
            assert np.isfinite(c.punch_deviation_mm).any()
            assert Path(c.job_path).exists()
            # the simulated scanner wrote the reference mark and compare used it for the start
            assert Path(c.scan_path + ".mark.json").exists()
            assert "reference mark" in c.comparison["notes"][0]
        # the correction moved the strokes by what was measured
        moved = cycles[1].steps[0].lower_mm - cycles[0].steps[-1].lower_mm
        assert np.nanmax(np.abs(moved)) > 0.1
        # ... through the plate model calibrated on the measured cycle (its yield stress fitted)
        assert "plate model calibrated on 1 cycle(s)" in cycles[1].correction["notes"][0]
    # the audit log has exactly one GO per press step, each with its cycle's job hash
    audit = sqlite3.connect(tmp_path / "audit.sqlite")
    for c in cycles:
        (gos,) = audit.execute("SELECT COUNT(*) FROM audit WHERE action = 'go' AND outcome = 'ok' "
                               "AND job_sha256 = ?", (c.job_sha256,)).fetchone()
        assert gos == len(c.steps)


def test_loop_with_a_bad_design_file_exits_2_without_planning(plate_files, tmp_path, capsys):
    _, flat = plate_files
    bad = tmp_path / "design.csv"
    bad.write_text("x,y,z\n1,2,oops\n")
    assert main(loop_args(bad, flat, tmp_path)) == 2
    err = capsys.readouterr().err
    assert "design.csv" in err and "line" in err
    assert not (tmp_path / "audit.sqlite").exists()


def test_loop_with_a_flat_of_another_plate_exits_2(hull_dir, plate_files, tmp_path, capsys):
    _, flat = plate_files
    other = hull_dir / "P1_midbody_bilge_smooth.csv"
    assert main(loop_args(other, flat, tmp_path)) == 2
    err = capsys.readouterr().err
    assert "error:" in err and "Traceback" not in err
    with History(tmp_path / "history.sqlite") as history:
        assert history.plates() == []  # nothing recorded, nothing pressed


def test_loop_option_errors_exit_2(plate_files, tmp_path, capsys):
    design, flat = plate_files
    assert main(loop_args(design, flat, tmp_path, "--tolerance", "-1")) == 2
    assert "tolerance_mm must be a positive number" in capsys.readouterr().err
    assert main(["loop", str(design), "--history", str(tmp_path / "h.sqlite")]) == 2
    assert "needs DESIGN, FLAT" in capsys.readouterr().err
    assert main(["loop", "--resume", "--history", str(tmp_path / "h.sqlite")]) == 2
    assert "no unfinished plate" in capsys.readouterr().err
    assert main(loop_args(design, flat, tmp_path, "--plc", "http://press:80")) == 2
    assert "http://press:80" in capsys.readouterr().err
    assert main(loop_args(design, flat, tmp_path, "--scanner", str(tmp_path / "no-such-folder"))) == 2
    assert "no-such-folder" in capsys.readouterr().err
    with History(tmp_path / "history.sqlite") as history:
        assert history.plates() == []  # refused before planning: nothing recorded


def test_loop_with_a_bad_scan_file_exits_2_and_resumes(plate_files, tmp_path, capsys):
    design, flat = plate_files
    scans = tmp_path / "scans"
    scans.mkdir()
    (scans / "scan1.csv").write_text("this is not a point file\n")
    # saved "during the cycle": newer than the plan the loop is about to record
    later = time.time() + 600
    os.utime(scans / "scan1.csv", (later, later))
    args = loop_args(design, flat, tmp_path, "--plate-id", "K2-B", "--scanner", str(scans), "--scan-timeout", "5",
                     "--max-cycles", "1")
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "scan1.csv" in err and "Traceback" not in err
    with History(tmp_path / "history.sqlite") as history:
        assert history.cycle("K2-B", 1).state == "pressed"  # pressed, waiting for a usable scan
    # a scan saved in metres (the plate 1000 times too small) is refused by the comparison
    (scans / "scan1.csv").unlink()
    write_points(scans / "scan2.csv", read_points(design).points / 1000.0)
    assert main(["loop", "--resume", "--plate-id", "K2-B", "--history", str(tmp_path / "history.sqlite"),
                 "--scan-timeout", "5"]) == 2
    err = capsys.readouterr().err
    assert "not the same plate" in err and "--units" in err
    with History(tmp_path / "history.sqlite") as history:
        record = history.cycle("K2-B", 1)
        # both scans rejected, never taken again; the cycle waits for a new scan
        assert record.state == "pressed" and record.steps_done == len(record.steps)
        assert [Path(r["path"]).name for r in record.rejected_scans] == ["scan1.csv", "scan2.csv"]
        # the operator scans again: here the simulated scan of the plate as pressed
        press = load_press(example_press_path())
        scanner = _scanner(history, "K2-B", press, flat)
        upper, lower = record.steps[-1].setpoints_mm(press)
        scanner.acquire(1, ScanContext(plate_id="K2-B", work_dir=scans, since_s=time.time(), upper_mm=upper,
                                       lower_mm=lower, active=record.steps[-1].active))
    assert main(["loop", "--resume", "--plate-id", "K2-B", "--history", str(tmp_path / "history.sqlite"),
                 "--scan-timeout", "5"]) == 0
    with History(tmp_path / "history.sqlite") as history:
        record = history.cycle("K2-B", 1)
    assert record.state == "done" and Path(record.scan_path).name == "scan-cycle-01.ply"
    audit = sqlite3.connect(tmp_path / "audit.sqlite")
    (gos,) = audit.execute("SELECT COUNT(*) FROM audit WHERE action = 'go'").fetchone()
    assert gos == len(record.steps)  # the resumes pressed nothing


# -- refusals and faults on the real simulated PLC (in-process, run_loop directly) -------------------


def _start(tmp_path, plate_files, history, plate_id, max_cycles=1):
    from mppf.loop.cycle import start_plate
    from mppf.planning.press import load_press

    design, flat = plate_files
    press = load_press(example_press_path())
    start_plate(history, read_points(design), read_points(flat), press, 20.0, plate_id=plate_id,
                work_dir=tmp_path / plate_id, settings=LoopSettings(max_cycles=max_cycles))
    return press


def _scanner(history, plate_id, press, flat_path):
    from mppf.planning.job import load_job
    from mppf.sim.shop import SimulatedPlateScanner

    job = load_job(history.cycle(plate_id, 1).job_path)
    return SimulatedPlateScanner.for_job(press, 20.0, job, read_points(flat_path).points, seed=1)


def test_a_refused_step_is_not_started_and_is_pressed_on_resume(plate_files, tmp_path):
    from mppf.drivers.audit import AuditLog
    from mppf.drivers.modbus import ModbusPress
    from mppf.core.errors import PressRefused
    from mppf.loop.cycle import run_loop
    from mppf.sim.plc import run_simulated_plc

    with History(tmp_path / "h.sqlite") as history, AuditLog(tmp_path / "audit.sqlite") as audit:
        press = _start(tmp_path, plate_files, history, "R1")
        scanner = _scanner(history, "R1", press, plate_files[1])
        with run_simulated_plc(press, time_scale=200) as sim, \
                ModbusPress(sim.url, press, audit=audit, timeout_s=5.0) as link:
            sim.inject("estop")  # the e-stop is pressed: the PLC refuses the upload
            with pytest.raises(PressRefused, match="e-stop"):
                run_loop(history, "R1", link, scanner)
            record = history.cycle("R1", 1)
            assert record.state == "planned" and record.step_started == 0  # nothing moved: may press later
            assert [e.action for e in audit.entries() if e.action == "go"] == []
            # the operator releases the e-stop and resets; the resumed loop presses the cycle
            sim.release_estop()
            link.reset()
            result = run_loop(history, "R1", link, scanner)
        assert result.status in ("in_tolerance", "max_cycles") and result.resumed_state == "planned"
        gos = [e for e in audit.entries() if e.action == "go" and e.outcome == "ok"]
        assert len(gos) == len(result.cycles[0].steps)


def test_a_fault_during_motion_leaves_the_cycle_pressing_and_resume_measures_it(plate_files, tmp_path):
    from mppf.drivers.audit import AuditLog
    from mppf.drivers.modbus import ModbusPress
    from mppf.core.errors import PressFault
    from mppf.loop.cycle import run_loop
    from mppf.sim.plc import run_simulated_plc

    with History(tmp_path / "h.sqlite") as history, AuditLog(tmp_path / "audit.sqlite") as audit:
        press = _start(tmp_path, plate_files, history, "F1")
        scanner = _scanner(history, "F1", press, plate_files[1])
        with run_simulated_plc(press, time_scale=50) as sim, \
                ModbusPress(sim.url, press, audit=audit, timeout_s=5.0) as link:
            sim.inject("overpressure", after_s=2.0)  # hydraulic fault 2 s into the first motion
            with pytest.raises(PressFault):
                run_loop(history, "F1", link, scanner)
            record = history.cycle("F1", 1)
            assert record.state == "pressing" and (record.step_started, record.steps_done) == (1, 0)
            gos_before = sum(1 for e in audit.entries() if e.action == "go")
            result = run_loop(history, "F1", link, scanner)  # resume: measure, never press again
        first = result.cycles[0]
        assert result.resumed_state == "pressing" and first.interrupted and first.scan_sha256
        assert sum(1 for e in audit.entries() if e.action == "go") == gos_before == 1


def test_reference_mark_file_is_read_and_a_bad_one_refused(tmp_path):
    from mppf.measure.mark import reference_mark
    from mppf.planning.job import Job, PlateLayout, StepStrokes, reference_corner_xy

    press = load_press(example_press_path())
    active = np.zeros(press.shape, dtype=bool)
    active[:3, :3] = True
    steps = [StepStrokes(np.where(active, 20.0, np.nan), np.where(active, 0.0, np.nan), active)]
    outline = [[-500.0, -300.0], [500.0, -300.0], [500.0, 300.0], [-500.0, 300.0]]
    job = Job(press=press, thickness_mm=20.0, steps=steps, tf_press_design=np.eye(4), tf_press_flat=np.eye(4),
              layout=PlateLayout(outline, outline))
    assert np.allclose(reference_corner_xy(outline), [-500.0, -300.0])
    gx, gy = np.meshgrid(np.linspace(-500, 500, 11), np.linspace(-300, 300, 7))
    design = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])
    scan = tmp_path / "scan.ply"
    assert reference_mark(scan, design, job) is None  # no mark file: register without it
    Path(str(scan) + ".mark.json").write_text(json.dumps({"reference_mark_mm": [1.0, 2.0, 3.0]}))
    measured, on_design = reference_mark(scan, design, job)
    assert np.allclose(measured, [1.0, 2.0, 3.0]) and np.allclose(on_design, [-500.0, -300.0, 0.0])
    Path(str(scan) + ".mark.json").write_text(json.dumps({"reference_mark_mm": [1.0, 2.0]}))
    with pytest.raises(InputError, match="reference mark"):
        reference_mark(scan, design, job)
