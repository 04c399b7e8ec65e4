"""The loop asks an outside scanner station for a rescan of the areas not measured, and compares the union.

The station (tests/rescan_station.py, another process) scans the plate as designed with a
hole (a clamp) first, then, for the rescan request, only the requested areas in the same
frame; shifted 5 mm, the rescan disagrees with the first scan and is not merged.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest
from station_helpers import asymmetric_points, planned_plate, request_keeper, station_log

import mppf.loop.rescanning as rescanning
from mppf.drivers.audit import AuditLog
from mppf.loop.cycle import run_loop
from mppf.loop.history import History
from mppf.loop.options import LoopOptions, PlateInputs
from mppf.loop.plate import record_plate
from mppf.loop.scanners import DirectoryScanner
from mppf.loop.settings import LoopSettings
from mppf.loop.states import CycleState
from mppf.sim.plc.link import InProcessPress

STATION = Path(__file__).parents[1] / "rescan_station.py"
SETTINGS = dict(max_cycles=1, margin_mm=0.0, mark_settle_s=0.5, mark_timeout_s=8.0)


@pytest.fixture(scope="module")
def bump(tmp_path_factory):
    """The asymmetric plate of the station tests, planned: (design, flat, press, job)."""
    return planned_plate(tmp_path_factory.mktemp("bump"), "bump", asymmetric_points(), LoopSettings(**SETTINGS))


def _run(tmp_path, plate, *station_args, rescans=2, requests=2, station=True, **settings):
    design, flat, press, job = plate
    folder = tmp_path / "scans"
    folder.mkdir(exist_ok=True)
    history = History(tmp_path / "h.sqlite")
    if not history.plates():
        record_plate(history, PlateInputs(design, flat, press, 20.0), job, plate_id="RS", work_dir=tmp_path / "RS",
                     options=LoopOptions(settings=LoopSettings(**SETTINGS, rescans=rescans, **settings)))
    station = subprocess.Popen([sys.executable, str(STATION), str(folder), str(design.path), "--requests",
                                str(requests), "--idle", "20", *station_args],
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True) if station else None
    reporter, requests_seen = request_keeper()  # every request the loop writes, to read it afterwards
    try:
        with AuditLog(tmp_path / "audit.sqlite") as audit, InProcessPress(press, audit=audit) as link:
            result = run_loop(history, "RS", link, DirectoryScanner(folder, timeout_s=30.0, poll_s=0.2),
                              reporter=reporter)
        comparison = history.cycle("RS", 1).comparison
    finally:
        lines = station_log(station) if station else []
        history.close()
    return result, reporter.messages, lines, comparison, requests_seen


def test_the_station_rescans_the_hidden_area_and_the_union_is_in_tolerance(bump, tmp_path):
    result, messages, lines, comparison, requests = _run(tmp_path, bump)
    assert result.status == "in_tolerance", messages
    # the loop said what it asked for, the station answered the rescan request with the areas only
    asked = [m for m in messages if "asking for rescan 1 of 2" in m]
    assert len(asked) == 1 and "1 area(s) not measured" in asked[0]
    assert [line.split()[0] for line in lines] == ["request", "hole", "scan", "gone", "request", "scan", "gone", "done"]
    doc = requests["RS-cycle-01-rescan-1.scan-request.json"]
    assert doc["rescan"] == 1 and doc["rescans"] == 2 and doc["scan"]["path"].endswith("RS-cycle-01-rescan-1.ply")
    assert doc["first_scan"]["path"].endswith("RS-cycle-01.ply") and doc["mark"]["required"] is False
    region = doc["regions"][0]
    assert len(region["corners_press_mm"]) == 4 and len(region["centroid_uv_mm"]) == 2
    # the hole (the net plate's middle) lies inside the requested box
    hole = [float(v) for v in lines[1].split()[2:4]]
    (x0, x1), (y0, y1) = [(min(c), max(c)) for c in zip(*region["corners_press_mm"])]
    assert x0 < hole[0] < x1 and y0 < hole[1] < y1
    # both files recorded with the comparison, the rescan merged after the overlap check
    first, rescan = comparison["scans"]
    assert first["rescan"] == 0 and rescan["rescan"] == 1 and rescan["merged"] and rescan["agreement"]["agrees"]
    assert rescan["n_points"] < first["n_points"] and comparison["n_points"] == first["n_points"] + rescan["n_points"]
    assert comparison["coverage"]["complete"] and comparison["rescan_stopped"] is None
    assert not list((tmp_path / "scans").glob("*.scan-request.json"))


def test_a_rescan_shifted_5_mm_is_not_merged_and_the_cycle_needs_review(bump, tmp_path):
    result, _, _, comparison, _ = _run(tmp_path, bump, "--shift", "5")
    assert result.status == "needs_review"
    assert "rescan 1 (RS-cycle-01-rescan-1.ply) not merged" in result.verdict
    assert "the plate or the scanner moved" in result.verdict
    rescan = comparison["scans"][1]
    assert not rescan["merged"] and not rescan["agreement"]["agrees"]
    assert 4.0 < rescan["agreement"]["difference_mm"] < 6.0
    # the verdict is the first scan's: the area stays not measured
    assert not comparison["coverage"]["complete"] and comparison["rescan_stopped"] in result.verdict
    assert comparison["n_points"] == comparison["scans"][0]["n_points"]


def test_no_rescans_keeps_the_old_needs_review(bump, tmp_path):
    result, messages, _, comparison, requests = _run(tmp_path, bump, rescans=0, requests=1)
    assert result.status == "needs_review" and "not measured" in result.verdict and result.ending.exit_code == 6
    assert not any("asking for rescan" in m or "rescan 1" in m for m in messages)
    assert list(requests) == ["RS-cycle-01.scan-request.json"]
    assert len(comparison["scans"]) == 1 and not comparison["coverage"]["complete"]


def test_a_station_that_does_not_rescan_costs_one_short_wait(bump, tmp_path):
    # the station answers the cycle's scan request, never the rescan request
    start = time.monotonic()
    result, messages, _, comparison, _ = _run(tmp_path, bump, requests=1, rescan_timeout_s=1.0)
    assert result.status == "needs_review"
    assert any("asking for rescan 1 of 2" in m for m in messages)
    assert any("waiting for rescan 1" in m and "(up to 1 s)" in m for m in messages)
    assert any("no rescan came" in m and "no further rescan is asked in this run" in m for m in messages)
    assert not any("rescan 2" in m for m in messages)
    assert len(comparison["scans"]) == 1 and not comparison["coverage"]["complete"]
    assert time.monotonic() - start < 25.0  # not the scanner's 30 s


def test_after_one_unanswered_rescan_request_the_run_asks_for_no_more(monkeypatch):
    from types import SimpleNamespace

    from driver_helpers import HookReporter

    class Station:
        calls = 0

        def rescan(self, *args):
            Station.calls += 1

    monkeypatch.setattr(rescanning, "load_cycle_job", lambda record: None)
    monkeypatch.setattr(rescanning, "_rescannable", lambda verdict: True)
    run = SimpleNamespace(settings=LoopSettings(rescans=2), reporter=HookReporter(), scanner=Station(),
                          known={rescanning.UNANSWERED: "cycle 1, rescan 1"})
    record = SimpleNamespace(scan_path="scan-02.ply", scan_sha256="", cycle=2)
    comparison = SimpleNamespace(n_points=100, verdict=None)
    measured = rescanning.rescan_uncovered(run, record, comparison)
    assert measured.comparison is comparison and len(measured.scans) == 1 and Station.calls == 0
    assert any("no rescan asked" in m and "cycle 1, rescan 1" in m for m in run.reporter.messages)


def test_a_rescan_taken_before_a_crash_is_not_lost_on_resume(bump, tmp_path, monkeypatch):
    def crash(*args, **kwargs):
        raise KeyboardInterrupt  # the power went while the union was being compared

    monkeypatch.setattr(rescanning, "compare_union", crash)
    with pytest.raises(KeyboardInterrupt):
        _run(tmp_path, bump)
    with History(tmp_path / "h.sqlite") as history:
        assert history.cycle("RS", 1).state == CycleState.SCANNED
    monkeypatch.undo()
    # resumed without the station: the rescan already in the folder is taken again, merged
    result, messages, _, comparison, requests = _run(tmp_path, bump, station=False)
    assert result.status == "in_tolerance", messages
    assert any("asking for rescan 1 of 2" in m for m in messages) and "RS-cycle-01-rescan-1.scan-request.json" in requests
    _, rescan = comparison["scans"]
    assert rescan["merged"] and rescan["path"] == str((tmp_path / "scans" / "RS-cycle-01-rescan-1.ply").resolve())
