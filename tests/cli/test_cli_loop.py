"""``mppf loop``: convergence on the simulated press, bad input, a bad scan and resume, the press policy."""

from __future__ import annotations

import io
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

from mppf.cli import main
from mppf.core.scanner import ScanContext
from mppf.drivers.audit import AuditLog
from mppf.geometry.read import read_points
from mppf.geometry.unfold import unfold
from mppf.geometry.write import write_points
from mppf.loop.history import History
from mppf.loop.options import LoopOptions, PlateInputs
from mppf.loop.plate import record_plate
from mppf.loop.settings import LoopSettings
from mppf.model.press import example_press_path, load_press

CONVERGING_PLATE = "P1_midbody_bilge_smooth"  # the DTC midship bilge, the demo's plate


def _design_and_flat(folder: Path, hull_dir: Path, name: str) -> tuple[Path, Path]:
    design = hull_dir / f"{name}.csv"
    return design, write_points(folder / f"{name}.flat.csv", unfold(read_points(design).points).flat)


def loop_args(design, flat, home: Path, *extra) -> list[str]:
    return ["loop", str(design), str(flat), "--press", str(example_press_path()), "--thickness", "20",
            "--history", str(home / "history.sqlite"), "--time-scale", "200", *extra]


@pytest.mark.slow  # minutes of simulation: 2-4 cycles of the steel-plate simulator, compared on dense scans
def test_loop_converges_on_the_simulated_press(hull_dir, tmp_path, capsys):
    design, flat = _design_and_flat(tmp_path, hull_dir, CONVERGING_PLATE)
    # seed 2: a plate whose first cycle is out of tolerance (the loop has to correct it)
    code = main(loop_args(design, flat, tmp_path, "--plate-id", "P1-A", "--seed", "2", "--json",
                          "--operator", "A. Operator"))
    out = capsys.readouterr().out
    doc = json.loads(out)
    # formed to tolerance; "needs_review" when scanner artefacts set aside lie beyond the tolerance (exit 6)
    assert doc["status"] in ("in_tolerance", "needs_review")
    assert code == {"in_tolerance": 0, "needs_review": 6}[doc["status"]], out
    assert doc["verdict"] == doc["ending"]["text"] and doc["ending"]["exit_code"] == code
    last = doc["cycles"][-1]
    assert last["max_abs_mm"] <= 2.5 and last["rms_mm"] <= 1.0 and last["state"] == "done"
    assert 2 <= len(doc["cycles"]) <= 4  # 4 on the steel-plate simulator with the spacing-aware form max
    with History(tmp_path / "history.sqlite") as history:
        cycles = history.cycles("P1-A")
        work = Path(history.plate("P1-A").settings["work_dir"])
        # the plate's report, written by default into its work folder: who, when, which press, which jobs
        report = (work / "report.html").read_text()
        assert "A. Operator" in report and "report made (UTC)" in report and "@media print" in report
        assert all(c.job_sha256 in report for c in cycles) and report.count("data:image/png;base64,") >= 2 * len(cycles)
        assert all((work / f"punch-deviation-cycle-{c.cycle}.png").exists() for c in cycles)
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
    # the report again, afterwards, from the history and the recorded scans
    (work / "report.html").unlink()
    (work / "deviation-cycle-1.png").unlink()
    assert main(["history", "--history", str(tmp_path / "history.sqlite"), "--report", "P1-A"]) == 0
    assert "report of plate P1-A" in capsys.readouterr().out
    assert (work / "deviation-cycle-1.png").exists() and cycles[-1].job_sha256 in (work / "report.html").read_text()


@pytest.mark.slow  # one simulated cycle, compared on a dense scan: 5-9 s
def test_a_loop_out_of_cycles_exits_5_with_its_verdict(plate_files, tmp_path, capsys):
    design, flat = plate_files
    code = main(loop_args(design, flat, tmp_path, "--max-cycles", "1", "--json", "--no-report"))
    doc = json.loads(capsys.readouterr().out)
    assert code == 5 and doc["status"] == "max_cycles"  # the first press is 15-40 mm off: not in tolerance
    end = doc["ending"]
    assert doc["verdict"] == end["text"] and end["decision"] == "max_cycles" and end["exit_code"] == 5
    assert "1 cycles pressed, cycle 1: form max" in end["why"] and end["region"].startswith("largest form deviation")
    assert "--max-cycles" in end["advice"] and end["text"].startswith("max cycles: ")


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
    assert "tolerance_mm must be above 0" in capsys.readouterr().err
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
    # the good scan is taken: the loop ends after its one cycle (the steel plate's first press under-bends: exit 5)
    assert main(["loop", "--resume", "--plate-id", "K2-B", "--history", str(tmp_path / "history.sqlite"),
                 "--scan-timeout", "5"]) == 5
    with History(tmp_path / "history.sqlite") as history:
        record = history.cycle("K2-B", 1)
    assert record.state == "done" and Path(record.scan_path).name == "scan-cycle-01.ply"
    assert record.decision == "max_cycles"
    audit = sqlite3.connect(tmp_path / "audit.sqlite")
    (gos,) = audit.execute("SELECT COUNT(*) FROM audit WHERE action = 'go'").fetchone()
    assert gos == len(record.steps)  # the resumes pressed nothing



def _scanner(history, plate_id, press, flat_path):
    from mppf.planning.job import load_job
    from mppf.sim.shop import SimulatedPlateScanner

    job = load_job(history.cycle(plate_id, 1).job_path)
    # the steel plate on a coarse grid: this scan only has to be a usable scan of the plate as pressed, seen whole
    # without stray returns (no rescan is asked for)
    return SimulatedPlateScanner.for_job(press, 20.0, job, read_points(flat_path).points, seed=1,
                                         plate_options={"grid_spacing_mm": 150.0}, occlusion_fraction=0.0,
                                         outlier_fraction=0.0)


# -- the press policy, shared with mppf press ------------------------------------------------------


def _recorded(tmp_path, planned_plate, plate_id, **setup):
    """A plate recorded from the session's planned job into ``tmp_path/history.sqlite`` (no planning)."""
    design, flat, press, job = planned_plate
    with History(tmp_path / "history.sqlite") as history:
        record_plate(history, PlateInputs(design, flat, press, 20.0), job, plate_id=plate_id,
                     work_dir=tmp_path / plate_id,
                     options=LoopOptions(settings=LoopSettings(max_cycles=1),
                                         setup={"scanner": "sim", "seed": 1, **setup}))
    return tmp_path / "history.sqlite"


def test_a_real_press_without_a_terminal_is_refused_with_exit_4(planned_plate, tmp_path, monkeypatch, capsys):
    from mppf.sim.plc.host import run_simulated_plc

    db = _recorded(tmp_path, planned_plate, "NT-1")
    monkeypatch.setattr("sys.stdin", io.StringIO(""))  # not a terminal
    with run_simulated_plc(planned_plate[2], time_scale=200) as real:  # any PLC at --plc is asked for
        code = main(["loop", "--resume", "--plate-id", "NT-1", "--history", str(db), "--plc", real.url])
        moved = not np.allclose(real.actual_positions_mm()[0], planned_plate[2].upper.park_mm)
    assert code == 4  # as mppf press: a refusal, not a cancellation
    assert "without confirmation" in " ".join(capsys.readouterr().err.split())
    with History(db) as history, AuditLog(tmp_path / "audit.sqlite") as audit:
        assert history.cycle("NT-1", 1).state == "planned"  # nothing sent: the plate can be pressed later
        assert [e.action for e in audit.entries()] == ["connect"] and not moved


def _sent_go(audit: Path) -> bool:
    if not audit.exists():
        return False
    with AuditLog(audit) as log:
        return any(e.action == "go" for e in log.entries())


def test_sigterm_during_a_dry_run_stops_the_press_first_and_exits_130(planned_plate, tmp_path):
    db = _recorded(tmp_path, planned_plate, "TERM-1")
    env = {**os.environ, "MPPF_HOME": str(tmp_path / "home")}
    # real-time motion: the first move takes seconds, SIGTERM arrives while the punches move
    proc = subprocess.Popen([sys.executable, "-m", "mppf", "loop", "--resume", "--plate-id", "TERM-1", "--history",
                             str(db), "--time-scale", "1"], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    audit = tmp_path / "audit.sqlite"
    try:
        deadline = time.monotonic() + 60
        while not _sent_go(audit):
            assert proc.poll() is None, proc.communicate()[1]
            assert time.monotonic() < deadline, "mppf loop did not send GO"
            time.sleep(0.05)
        time.sleep(0.3)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    err = " ".join(err.split())
    assert proc.returncode == 130, err
    assert "cancelled by the operator; STOP was sent" in err and "Traceback" not in err
    with AuditLog(audit) as log:
        assert [(e.action, e.outcome) for e in log.entries() if e.action != "release"][-2:] == [("go", "ok"),
                                                                                               ("stop", "ok")]
    with History(db) as history:
        assert history.cycle("TERM-1", 1).state == "pressing"  # never pressed again
