"""The simulated scanner station (sim/station.py): its plate follows the tips the PLC reached, its scans answer the loop.

The loop runs in this process on the in-process press (the simulated PLC's program) with a
directory scanner; the station, in a thread, follows that program's scans and answers the
loop's scan requests in the folder, as ``mppf sim --station`` does in its own process
(tests/cli/test_cli_sim_station.py).
"""

from __future__ import annotations

import json
import threading

import numpy as np
import pytest
from station_helpers import asymmetric_points, planned_plate

from mppf.core.errors import InputError, PressFault
from mppf.drivers.audit import AuditLog
from mppf.geometry.read import read_points
from mppf.loop.cycle import run_loop
from mppf.loop.history import History
from mppf.loop.options import LoopOptions, PlateInputs
from mppf.loop.plate import record_plate
from mppf.loop.scanners import DirectoryScanner
from mppf.loop.settings import LoopSettings
from mppf.model.press import example_press_path, load_press
from mppf.sim.plc.link import InProcessPress
from mppf.sim.shop import SimulatedPlateScanner
from mppf.sim.station import MotionLog, ScanStation, active_pairs

SETTINGS = {"max_cycles": 1, "margin_mm": 0.0, "mark_settle_s": 0.5, "mark_timeout_s": 8.0, "rescans": 0}


@pytest.fixture(scope="module")
def bump(tmp_path_factory):
    """The asymmetric plate of the station tests, planned: (design, flat, press, job)."""
    return planned_plate(tmp_path_factory.mktemp("bump"), "bump", asymmetric_points(), LoopSettings(**SETTINGS))


def _loop_with_station(tmp_path, plate):
    """One cycle of the loop on the in-process press, its scans from the station: (result, station, lines)."""
    design, flat, press, job = plate
    folder = tmp_path / "scans"
    lines: list[str] = []
    log = MotionLog(press)
    station = ScanStation(folder, press, log, say=lines.append)
    stop = threading.Event()
    with History(tmp_path / "h.sqlite") as history:
        record_plate(history, PlateInputs(design, flat, press, 20.0), job, plate_id="ST", work_dir=tmp_path / "ST",
                     options=LoopOptions(settings=LoopSettings(**SETTINGS)))
        with AuditLog(tmp_path / "audit.sqlite") as audit, InProcessPress(press, audit=audit) as link:
            log.follow(link.program)
            thread = threading.Thread(target=station.run, args=(stop,), daemon=True)
            thread.start()
            try:
                result = run_loop(history, "ST", link, DirectoryScanner(folder, timeout_s=60.0, poll_s=0.2))
            finally:
                stop.set()
                thread.join(timeout=30)
    return result, station, lines


@pytest.mark.slow  # a loop cycle: about 8 s
def test_the_station_presses_the_tips_the_plc_reached_and_answers_the_request(bump, tmp_path):
    _, flat, press, job = bump
    result, station, lines = _loop_with_station(tmp_path, bump)
    assert result.status in ("in_tolerance", "needs_review", "max_cycles"), lines
    # every motion of the cycle pressed, in order: the tips where the PLC brought them, the pairs the job used
    steps = station.cycle_steps[("ST", 1)]
    assert [s.step for s in steps] == list(range(1, len(job.steps) + 1))
    for pressed, planned in zip(steps, job.steps):
        upper, lower = planned.setpoints_mm(press)
        assert np.array_equal(pressed.active, np.asarray(planned.active, dtype=bool))
        assert np.abs(pressed.upper_mm - upper)[pressed.active].max() <= press.position_tolerance_mm
        assert np.abs(pressed.lower_mm - lower)[pressed.active].max() <= press.position_tolerance_mm
    assert f"station: ST cycle 1: pressing {len(job.steps)} motion(s) on the fd plate" in lines
    scan = tmp_path / "scans" / "ST-cycle-01.ply"
    mark = json.loads((tmp_path / "scans" / "ST-cycle-01.ply.mark.json").read_text())
    assert len(mark["reference_mark_mm"]) == 3 and not list((tmp_path / "scans").glob("*.scan-request.json"))
    # the same plate pressed in this process with the job's setpoints gives the same scan within the PLC's
    # position tolerance; pressed with its first step only, a scan far from it (the test can fail)
    reference = SimulatedPlateScanner.for_job(press, 20.0, job, flat.points, seed=0)
    first_only = SimulatedPlateScanner.for_job(press, 20.0, job, flat.points, seed=0)
    for k, planned in enumerate(job.steps):
        reference.plate.press_step(*planned.setpoints_mm(press), planned.active)
        if k == 0:
            first_only.plate.press_step(*planned.setpoints_mm(press), planned.active)
    seen = read_points(scan).points
    same = read_points(reference.scan_formed(1, reference.plate.formed, tmp_path / "ref.ply")).points
    other = read_points(first_only.scan_formed(1, first_only.plate.formed, tmp_path / "first.ply")).points
    assert seen.shape == same.shape == other.shape
    assert np.abs(seen - same).max() < 0.5
    assert np.abs(seen - other).max() > 5.0
    # asked again with no motion since: the plate as it lies, the same take
    again = station.answer({"plate_id": "ST", "cycle": 1, "rescan": 0, "written_utc": "again",
                            "job": {"path": str(tmp_path / "ST" / "cycle-01.job.json")},
                            "scan": {"path": str(tmp_path / "scans" / "again.ply")},
                            "mark": {"path": str(tmp_path / "scans" / "again.ply.mark.json")}})
    assert "station: ST cycle 1: no motion since its last scan: scanned as it lies" in lines
    assert np.abs(read_points(again).points - seen).max() < 1e-3


def test_parked_pairs_do_not_act_and_bad_requests_are_refused_with_a_message(tmp_path):
    press = load_press(example_press_path())
    upper = np.full(press.shape, press.upper.park_mm)
    lower = np.full(press.shape, press.lower.park_mm)
    upper[2, 3], lower[2, 3] = 30.0, 0.0
    assert active_pairs(press, upper, lower).sum() == 1 and active_pairs(press, upper, lower)[2, 3]
    lines: list[str] = []
    station = ScanStation(tmp_path / "scans", press, MotionLog(press), say=lines.append)
    (tmp_path / "scans" / "X-cycle-01.scan-request.json").write_text(json.dumps({"plate_id": "../X", "cycle": 1}))
    assert station.poll() == 0
    assert lines == [("station: request X-cycle-01.scan-request.json not answered: a scan request without 'scan' "
                      "(see docs/scanner-station.md for its keys)")]
    (tmp_path / "scans" / "X-cycle-01.scan-request.json").unlink()
    paths = {"scan": {"path": "a.ply"}, "mark": {"path": "a.ply.mark.json"}, "job": {"path": str(tmp_path / "no.json")}}
    (tmp_path / "scans" / "Y-cycle-01.scan-request.json").write_text(json.dumps({"plate_id": "Y", "cycle": "x", **paths}))
    (tmp_path / "scans" / "Z-cycle-01.scan-request.json").write_text(json.dumps({"plate_id": "Z", "cycle": 1, **paths}))
    assert station.poll() == 0 and station.poll() == 0  # each said once
    assert lines[1:] == [
        ("station: request Y-cycle-01.scan-request.json not answered: a scan request with cycle 'x', rescan 0 (the "
         "cycle and the rescan are whole numbers (docs/scanner-station.md))"),
        (f"station: request Z-cycle-01.scan-request.json not answered: job file {tmp_path / 'no.json'} does not "
         "exist (make one with 'mppf plan')")]
    with pytest.raises(InputError, match="unknown plate physics 'xx'"):
        ScanStation(tmp_path / "scans", press, MotionLog(press), physics="xx")


def test_the_motion_log_keeps_each_motion_where_the_tips_came_to_rest_complete_or_cut_short():
    from driver_helpers import small_press, step_setpoints

    press = small_press()
    upper, lower = step_setpoints(press)
    upper[0, 0], lower[0, 0] = press.upper.park_mm, press.lower.park_mm  # one pair parked
    log = MotionLog(press)
    with InProcessPress(press) as link:
        log.follow(link.program)
        link.run_step(upper, lower)
        (done,) = log.take()
        assert done.complete and log.take() == []
        assert np.abs(done.upper_mm - upper).max() <= press.position_tolerance_mm
        assert np.abs(done.lower_mm - lower).max() <= press.position_tolerance_mm
        assert not done.active[0, 0] and done.active.sum() == press.rows * press.cols - 1
        link.program.inject("overpressure", after_s=0.5)  # the PLC halts the next motion on its way
        with pytest.raises(PressFault):
            link.run_step(np.where(done.active, upper + 20.0, upper), np.where(done.active, lower + 20.0, lower))
        (cut,) = log.take()
        halted_upper, _ = link.program.actual_positions_mm()
    assert not cut.complete and np.array_equal(cut.upper_mm, halted_upper)
    moved = cut.upper_mm[cut.active] - upper[cut.active]
    assert 0.0 < np.median(moved) < 20.0 - press.position_tolerance_mm  # part of the way
