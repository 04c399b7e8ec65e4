"""``mppf loop --scanner FOLDER`` against an outside scanner station (tests/scan_station.py): request, mark, --on-pressed."""

from __future__ import annotations

import json
import sys

from station_helpers import plate_files, start_station, station_log, symmetric_points

from mppf.cli import main
from mppf.model.press import example_press_path


def _args(design, flat, home, *extra) -> list[str]:
    return ["loop", str(design), str(flat), "--press", str(example_press_path()), "--thickness", "20",
            "--history", str(home / "history.sqlite"), "--time-scale", "200", "--scanner", str(home / "scans"),
            "--margin", "0", "--max-cycles", "1", "--no-report", "--mark-settle", "1", *extra]


def test_loop_asks_for_the_scan_and_runs_the_on_pressed_command(tmp_path, capsys):
    design, flat = plate_files(tmp_path, "bowl", symmetric_points())
    (tmp_path / "scans").mkdir()
    seen = tmp_path / "seen.txt"
    trigger = f"{sys.executable} -c \"import os, sys; open({str(seen)!r}, 'w').write(os.environ['MPPF_SCAN_REQUEST'])\""
    station = start_station(tmp_path / "scans", design, "early")
    code = main(_args(design, flat, tmp_path, "--plate-id", "B1", "--on-pressed", trigger, "--json"))
    out, err = capsys.readouterr()
    lines = station_log(station)
    assert code == 0, err
    doc = json.loads(out)
    assert doc["status"] in ("in_tolerance", "needs_review")
    assert doc["cycles"][0]["comparison"]["registration"]["init"]["settled_by"] in ("mark", "held mark")
    assert seen.read_text().endswith("B1-cycle-01.scan-request.json")
    assert [line.split()[0] for line in lines] == ["request", "mark", "scan", "gone"]
    assert not list((tmp_path / "scans").glob("*.scan-request.json"))


def test_a_symmetric_plate_without_its_mark_waits_says_so_and_exits_4(tmp_path, capsys):
    design, flat = plate_files(tmp_path, "bowl", symmetric_points())
    (tmp_path / "scans").mkdir()
    station = start_station(tmp_path / "scans", design, "none")
    failing = f"{sys.executable} -c \"import sys; sys.exit('the scanner is off')\""
    code = main(_args(design, flat, tmp_path, "--plate-id", "B2", "--on-pressed", failing, "--mark-timeout", "2"))
    err = capsys.readouterr().err
    lines = station_log(station)
    assert code == 4
    # the failing trigger is reported and the loop goes on to wait for the scan
    assert "on-pressed command" in err and "failed (exit 1: the scanner is off)" in err
    # it says what it waits for, in which file, then stops with what to do
    assert "waiting for the reference mark of scan" in err and "B2-cycle-01.ply.mark.json" in err
    assert "no reference mark came for scan" in err and "mppf loop --resume --plate-id B2" in err
    assert lines[-1].startswith("gone")
