"""The loop's state machine on the in-process press: refusals, faults, Ctrl-C, limits, resume.

The press is :class:`mppf.sim.plc.link.InProcessPress` (the driver on the simulated PLC's
program, instant); the plate is planned once per session (``planned_plate``) and
recorded afresh by each test.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from driver_helpers import HookReporter

from mppf.core.errors import Cancelled, LimitError, PressFault, PressRefused
from mppf.drivers.audit import AuditLog
from mppf.loop.cycle import run_loop
from mppf.loop.history import History
from mppf.loop.options import LoopOptions, PlateInputs
from mppf.loop.plate import record_plate
from mppf.loop.settings import LoopSettings
from mppf.planning.job import load_job
from mppf.sim.plc.link import InProcessPress
from mppf.sim.shop import SimulatedPlateScanner


def _record(tmp_path, planned_plate, history, plate_id, max_cycles=1):
    """Record the planned plate as ``plate_id``; return its press."""
    design, flat, press, job = planned_plate
    record_plate(history, PlateInputs(design, flat, press, 20.0), job, plate_id=plate_id, work_dir=tmp_path / plate_id,
                 options=LoopOptions(settings=LoopSettings(max_cycles=max_cycles)))
    return press


COARSE_GRID_MM = 150.0
"""The steel plate's grid here (mm): coarse, the forming is not under test."""


def _scanner(history, plate_id, press, planned_plate):
    """The plate and its scanner: the steel plate on a coarse grid, since these tests are of the state machine
    (what is pressed, recorded and resumed), not of the forming. The scanner sees the whole plate without stray
    returns: no rescans (they have their own tests)."""
    job = load_job(history.cycle(plate_id, 1).job_path)
    return SimulatedPlateScanner.for_job(press, 20.0, job, planned_plate[1].points, seed=1,
                                         plate_options={"grid_spacing_mm": COARSE_GRID_MM},
                                         occlusion_fraction=0.0, outlier_fraction=0.0,
                                         spacing_mm=35.0)  # the cycle, not the scan, is under test


def _gos(audit, outcome="ok"):
    return [e for e in audit.entries() if e.action == "go" and (outcome is None or e.outcome == outcome)]


def test_a_refused_step_is_not_started_and_is_pressed_on_resume(planned_plate, tmp_path):
    with History(tmp_path / "h.sqlite") as history, AuditLog(tmp_path / "audit.sqlite") as audit:
        press = _record(tmp_path, planned_plate, history, "R1")
        scanner = _scanner(history, "R1", press, planned_plate)
        with InProcessPress(press, audit=audit) as link:
            link.program.inject("estop")  # the e-stop is pressed: the PLC refuses the upload
            with pytest.raises(PressRefused, match="e-stop"):
                run_loop(history, "R1", link, scanner)
            record = history.cycle("R1", 1)
            assert record.state == "planned" and record.step_started == 0  # nothing moved: may press later
            assert [e.action for e in audit.entries() if e.action == "go"] == []
            # the operator releases the e-stop and resets; the resumed loop presses the cycle
            link.program.release_estop()
            link.reset()
            result = run_loop(history, "R1", link, scanner)
        # the resumed loop pressed the cycle and judged it (needs review when two scans measured one of the
        # simulated scanner's spikes at one spot: no rule tells that from a narrow dent)
        assert result.status in ("in_tolerance", "max_cycles", "needs_review") and result.resumed_state == "planned"
        gos = _gos(audit)
        assert len(gos) == len(result.cycles[0].steps)


def test_a_job_file_changed_since_it_was_recorded_is_refused_and_nothing_is_pressed(planned_plate, tmp_path):
    from pathlib import Path

    from mppf.core.errors import ConfigError

    with History(tmp_path / "h.sqlite") as history, AuditLog(tmp_path / "audit.sqlite") as audit:
        press = _record(tmp_path, planned_plate, history, "J1")
        scanner = _scanner(history, "J1", press, planned_plate)
        path = Path(history.cycle("J1", 1).job_path)
        text = path.read_text()
        edited = text.replace('"thickness_mm": 20.0', '"thickness_mm": 20.5', 1)
        assert edited != text
        path.write_text(edited)  # the job edited by hand after it was recorded
        with InProcessPress(press, audit=audit) as link:
            with pytest.raises(ConfigError, match="changed after it was sealed.*changed: thickness"):
                run_loop(history, "J1", link, scanner)
        assert history.cycle("J1", 1).state == "planned" and history.cycle("J1", 1).step_started == 0
        assert _gos(audit, outcome=None) == []


def test_a_fault_during_motion_leaves_the_cycle_pressing_and_resume_measures_it(planned_plate, tmp_path):
    with History(tmp_path / "h.sqlite") as history, AuditLog(tmp_path / "audit.sqlite") as audit:
        press = _record(tmp_path, planned_plate, history, "F1")
        scanner = _scanner(history, "F1", press, planned_plate)
        with InProcessPress(press, audit=audit) as link:
            link.program.inject("overpressure", after_s=2.0)  # hydraulic fault 2 s into the first motion
            with pytest.raises(PressFault):
                run_loop(history, "F1", link, scanner)
            record = history.cycle("F1", 1)
            assert record.state == "pressing" and (record.step_started, record.steps_done) == (1, 0)
            gos_before = sum(1 for e in audit.entries() if e.action == "go")
            result = run_loop(history, "F1", link, scanner)  # resume: measure, never press again
        first = result.cycles[0]
        assert result.resumed_state == "pressing" and first.interrupted and first.scan_sha256
        assert sum(1 for e in audit.entries() if e.action == "go") == gos_before == 1


def test_ctrl_c_during_a_step_stops_the_press_and_the_cycle_is_never_pressed_again(planned_plate, tmp_path):
    def operator_presses_ctrl_c(completed):
        raise KeyboardInterrupt

    with History(tmp_path / "h.sqlite") as history, AuditLog(tmp_path / "audit.sqlite") as audit:
        press = _record(tmp_path, planned_plate, history, "C1")
        scanner = _scanner(history, "C1", press, planned_plate)
        with InProcessPress(press, audit=audit) as link:
            with pytest.raises(Cancelled, match="STOP was sent"):
                run_loop(history, "C1", link, scanner, reporter=HookReporter(on_update=operator_presses_ctrl_c))
            status = link.status()
        record = history.cycle("C1", 1)
        assert record.state == "pressing" and (record.step_started, record.steps_done) == (1, 0)
        assert [(e.action, e.outcome) for e in audit.entries() if e.action != "release"][-2:] == [("go", "ok"),
                                                                                                 ("stop", "ok")]
        assert not status.busy and not status.in_position  # braked to a standstill short of the targets


def test_strokes_beyond_the_plc_limits_are_refused_and_the_step_may_run_later(planned_plate, tmp_path):
    with History(tmp_path / "h.sqlite") as history, AuditLog(tmp_path / "audit.sqlite") as audit:
        press = _record(tmp_path, planned_plate, history, "L1")
        scanner = _scanner(history, "L1", press, planned_plate)
        highest = max(np.nanmax(s.upper_mm) for s in history.cycle("L1", 1).steps)
        limit = float(np.floor(highest - 1))
        tight = dataclasses.replace(press, upper=dataclasses.replace(press.upper, max_mm=limit, park_mm=limit))
        with InProcessPress(tight, audit=audit) as plc:  # a PLC whose own limits are tighter than the press file's
            with pytest.raises(LimitError, match="beyond the stroke limits, nothing was written"):
                run_loop(history, "L1", plc, scanner)
        record = history.cycle("L1", 1)
        assert record.state == "planned" and record.step_started == 0
        assert ("limits", "refused") in [(e.action, e.outcome) for e in audit.entries()] and _gos(audit, None) == []


def test_the_step_results_are_the_positions_the_program_reports(planned_plate, tmp_path):
    """Pressing a cycle records the program's actual positions and the simulated motion time."""
    from mppf.loop.pressing import press_cycle

    with History(tmp_path / "h.sqlite") as history:
        press = _record(tmp_path, planned_plate, history, "S1")
        record = history.cycle("S1", 1)
        with InProcessPress(press, noise_mm=0.002, seed=5) as link:
            press_cycle(history, record, press, link, HookReporter())
            final = link.program.actual_positions_mm()
        done = history.cycle("S1", 1)
    assert done.state == "pressed" and done.steps_done == len(done.steps) == len(done.results)
    last = done.results[-1]
    np.testing.assert_allclose(np.array(last["actual_lower_mm"], dtype=float), final[1], atol=0.02)
    upper, lower = record.steps[-1].setpoints_mm(press)
    np.testing.assert_allclose(final[0], upper, atol=press.position_tolerance_mm)
    assert all(r["duration_s"] > 1.0 for r in done.results)  # simulated seconds of motion, not wall time
