"""The loop and an outside scanner station: the scan request, marks early, late, in the header or missing, --on-pressed.

The loop runs in-process on the in-process press with the folder scanner; the station is
another process (tests/scan_station.py) that reads the request file, writes the scan and
its mark. Two small plates, each planned once: a symmetric bowl (needs the mark) and an
asymmetric one (the best fit is enough).
"""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest
from driver_helpers import HookReporter
from station_helpers import asymmetric_points, planned_plate, start_station, station_log, symmetric_points

from mppf.drivers.audit import AuditLog
from mppf.loop.cycle import run_loop
from mppf.loop.history import History
from mppf.loop.options import LoopOptions, PlateInputs
from mppf.loop.marks import MarkMissing, needs_mark
from mppf.loop.plate import record_plate
from mppf.loop.scan_request import REQUEST_FORMAT, REQUEST_VERSION, build_request, post_request, run_on_pressed
from mppf.loop.scanners import DirectoryScanner
from mppf.loop.settings import LoopSettings
from mppf.sim.plc.link import InProcessPress

SETTINGS = dict(max_cycles=1, margin_mm=0.0, mark_settle_s=1.0, mark_timeout_s=8.0)


def _planned(tmp_path_factory, name, points):
    return planned_plate(tmp_path_factory.mktemp(name), name, points, LoopSettings(**SETTINGS))


@pytest.fixture(scope="module")
def bowl(tmp_path_factory):
    """The symmetric bowl, planned: (design, flat, press, job)."""
    return _planned(tmp_path_factory, "bowl", symmetric_points())


@pytest.fixture(scope="module")
def bump(tmp_path_factory):
    """The asymmetric plate, planned."""
    return _planned(tmp_path_factory, "bump", asymmetric_points())


def _run(tmp_path, plate, mode, *, delay_s=2.0, settings=None, plate_id="S1", station=True):
    """Record the plate, start the station, run the loop: (result or the exception, messages, station lines, history).

    The history is open (the caller closes it).
    """
    design, flat, press, job = plate
    folder = tmp_path / "scans"
    folder.mkdir(exist_ok=True)
    history = History(tmp_path / "h.sqlite")
    record_plate(history, PlateInputs(design, flat, press, 20.0), job, plate_id=plate_id, work_dir=tmp_path / plate_id,
                 options=LoopOptions(settings=settings or LoopSettings(**SETTINGS)))
    process = start_station(folder, design.path, mode, delay_s=delay_s) if station else None
    reporter = HookReporter()
    with AuditLog(tmp_path / "audit.sqlite") as audit, InProcessPress(press, audit=audit) as link:
        try:
            outcome = run_loop(history, plate_id, link, DirectoryScanner(folder, timeout_s=30.0, poll_s=0.2),
                               reporter=reporter)
        except MarkMissing as exc:
            outcome = exc
    lines = station_log(process) if process else []
    return outcome, reporter.messages, lines, history


def _settled_by(history, plate_id="S1"):
    return history.cycle(plate_id, 1).comparison["registration"]["init"]["settled_by"]


def test_the_bowl_needs_its_mark_and_the_bump_does_not(bowl, bump):
    assert needs_mark(bowl[0].points).required
    need = needs_mark(bump[0].points)
    assert not need.required and need.asymmetry_mm > 4.0
    assert needs_mark(bump[0].points, residual_mm=need.asymmetry_mm).required  # a scan that far off would tie


def test_request_schema_and_the_mark_written_before_the_scan(bowl, tmp_path):
    result, messages, lines, history = _run(tmp_path, bowl, "early")
    with history:
        assert result.status in ("in_tolerance", "needs_review")
        assert _settled_by(history) in ("mark", "held mark")
    # the station read the request, wrote mark then scan, and saw the request removed once the scan was taken
    assert [line.split()[0] for line in lines] == ["request", "mark", "scan", "gone"]
    assert not list((tmp_path / "scans").glob("*.scan-request.json"))
    assert any("with its reference mark (mark file S1-cycle-01.ply.mark.json)" in m for m in messages)
    posted = next(m for m in messages if "scan request" in m)
    assert "S1-cycle-01.scan-request.json" in posted and "S1-cycle-01.ply.mark.json" in posted


def test_the_request_document(bowl, tmp_path):
    design, flat, press, job = bowl
    with History(tmp_path / "h.sqlite") as history:
        plate = record_plate(history, PlateInputs(design, flat, press, 20.0), job, plate_id="Q1",
                             work_dir=tmp_path / "Q1")
        doc = build_request(plate, history.cycle("Q1", 1), job, LoopSettings(), tmp_path, mark_required=True)
        # a folder that refuses the request: said, and the loop waits for the scan all the same
        reporter = HookReporter()
        posted = post_request(plate, history.cycle("Q1", 1), job, LoopSettings(on_pressed="/no/such/trigger"),
                              tmp_path / "no-such-folder", reporter)
        posted.withdraw()
        assert not posted.written and reporter.messages == [next(m for m in reporter.messages if "no scan request" in m)]
    assert doc["format"] == REQUEST_FORMAT and doc["version"] == REQUEST_VERSION and doc["cycle"] == 1
    assert doc["scan"]["path"].endswith("Q1-cycle-01.ply") and doc["mark"]["path"] == doc["scan"]["path"] + ".mark.json"
    assert doc["scan"]["skin"] == "top" and doc["scan"]["skin_offset_mm"] == 10.0 and "concave" in doc["scan"]["skin_meaning"]
    assert doc["mark"]["required"] is True and doc["plate"]["thickness_mm"] == 20.0
    # the mark is the corner of the outline as cut with the smallest x + y, in press coordinates
    cut = np.array(doc["plate"]["outline_cut_press_mm"])
    np.testing.assert_allclose(doc["mark"]["corner_press_mm"], cut[np.argmin(cut.sum(axis=1))], atol=1e-3)
    json.dumps(doc)  # JSON as it is


def test_a_mark_saved_after_the_scan_is_taken_is_used(bowl, tmp_path):
    # the scan counts as written after two steady polls (0.4 s); the mark comes 3 s after the scan
    result, messages, lines, history = _run(tmp_path, bowl, "late", delay_s=3.0)
    with history:
        assert result.status in ("in_tolerance", "needs_review") and _settled_by(history) in ("mark", "held mark")
    waiting = next(m for m in messages if "waiting for the reference mark" in m)
    assert "S1-cycle-01.ply.mark.json" in waiting and "not compared without it" in waiting
    assert any("came after the scan (mark file S1-cycle-01.ply.mark.json)" in m for m in messages)
    assert [line.split()[0] for line in lines] == ["request", "scan", "mark", "gone"]


def test_a_mark_in_the_scan_header(bowl, tmp_path):
    result, messages, _, history = _run(tmp_path, bowl, "header")
    with history:
        assert result.status in ("in_tolerance", "needs_review") and _settled_by(history) in ("mark", "held mark")
    assert any("with its reference mark (scan header)" in m for m in messages)
    assert not list((tmp_path / "scans").glob("*.mark.json"))


def test_a_symmetric_plate_without_its_mark_waits_then_stops_and_resumes_with_it(bowl, tmp_path):
    settings = LoopSettings(**{**SETTINGS, "mark_timeout_s": 2.0})
    stopped, messages, lines, history = _run(tmp_path, bowl, "none", settings=settings)
    assert isinstance(stopped, MarkMissing) and stopped.exit_code == 4
    assert "not compared without its mark" in stopped.message and "--resume" in stopped.hint
    assert any("waiting for the reference mark" in m and "S1-cycle-01.ply.mark.json" in m for m in messages)
    record = history.cycle("S1", 1)
    assert record.state == "pressed" and record.rejected_scans == []  # the scan waits, not rejected
    assert lines[-1].startswith("gone")  # the request is removed when the loop stops
    # the mark saved afterwards: the resumed loop takes the same scan with it
    scan = tmp_path / "scans" / "S1-cycle-01.ply"
    top = np.loadtxt(scan, skiprows=7)
    corner = top[np.argmin(top[:, 0] + top[:, 1])]
    (tmp_path / "scans" / "S1-cycle-01.ply.mark.json").write_text(json.dumps({"reference_mark_mm": corner.tolist()}))
    with history, AuditLog(tmp_path / "audit.sqlite") as audit, InProcessPress(bowl[2], audit=audit) as link:
        result = run_loop(history, "S1", link, DirectoryScanner(tmp_path / "scans", timeout_s=10.0, poll_s=0.2))
        assert result.status in ("in_tolerance", "needs_review") and _settled_by(history) in ("mark", "held mark")
        assert history.cycle("S1", 1).scan_path == str(scan.resolve())


def test_an_asymmetric_plate_without_a_mark_goes_on_by_the_best_fit(bump, tmp_path):
    result, messages, _, history = _run(tmp_path, bump, "none")
    with history:
        assert result.status in ("in_tolerance", "needs_review") and _settled_by(history) == "fit"
    note = next(m for m in messages if "no reference mark for scan S1-cycle-01.ply" in m)
    assert "registered by the best fit" in note and "not symmetric" in note
    assert not any("waiting for the reference mark" in m for m in messages)


def test_on_pressed_runs_with_the_request_and_a_failing_one_is_reported(bowl, tmp_path):
    seen = tmp_path / "seen.json"
    script = ("import json, os, sys; json.dump({'argv': sys.argv[1:], 'env': os.environ['MPPF_SCAN_REQUEST'], "
              f"'doc': json.load(open(sys.argv[-1]))}}, open({str(seen)!r}, 'w'))")
    command = f"{sys.executable} -c \"{script}\""
    settings = LoopSettings(**{**SETTINGS, "on_pressed": command})
    _, messages, _, history = _run(tmp_path, bowl, "early", settings=settings)
    history.close()
    doc = json.loads(seen.read_text())
    assert doc["argv"][-1] == doc["env"] and doc["env"].endswith("S1-cycle-01.scan-request.json")
    assert doc["doc"]["plate_id"] == "S1" and doc["doc"]["cycle"] == 1
    assert any("on-pressed command" in m and "done (exit 0)" in m for m in messages)
    # a failing command, one that cannot start, one that hangs: reported, never fatal
    reporter = HookReporter()
    assert run_on_pressed(f"{sys.executable} -c \"import sys; sys.exit('no scanner; 3')\"", seen, reporter, 30.0) == 1
    assert run_on_pressed("/no/such/scanner-trigger --go", seen, reporter, 30.0) is None
    assert run_on_pressed(f"{sys.executable} -c \"import time; time.sleep(30)\"", seen, reporter, 0.5) is None
    assert run_on_pressed("unbalanced 'quote", seen, reporter, 1.0) is None
    failed, missing, hung, unsplit = reporter.messages
    assert "failed (exit 1: no scanner; 3)" in failed and "goes on" in failed
    assert "could not start" in missing and "did not end within 0.5 s" in hung and "cannot split" in unsplit


def test_a_scan_that_cannot_be_of_the_plate_is_not_waited_on(bowl, tmp_path):
    from mppf.geometry.write import write_points
    from mppf.loop.marks import plausible_scan

    design = bowl[0].points
    garbage = tmp_path / "garbage.csv"
    garbage.write_text("this is not a point file\n")
    metres = write_points(tmp_path / "metres.csv", design / 1000.0)
    same = write_points(tmp_path / "same.csv", design + [5.0, -3.0, 10.0])
    assert not plausible_scan(garbage, design) and not plausible_scan(metres, design)
    assert plausible_scan(same, design)


def test_on_pressed_is_never_a_shell(tmp_path):
    marker = tmp_path / "injected"
    reporter = HookReporter()
    run_on_pressed(f"{sys.executable} -c pass; touch {marker}", tmp_path / "r.json", reporter, 30.0)
    assert not marker.exists()
