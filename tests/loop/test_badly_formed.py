"""The loop tells a badly formed plate from a wrong one (issue 20.5): the first stops with a verdict, the second is
refused and the cycle waits for another scan."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from mppf.core.errors import GeometryError
from mppf.core.transform import apply_tf
from mppf.drivers.audit import AuditLog
from mppf.geometry.frame import fit_frame
from mppf.geometry.write import write_points
from mppf.loop.cycle import run_loop
from mppf.loop.history import History
from mppf.loop.options import LoopOptions, PlateInputs
from mppf.loop.plate import record_plate
from mppf.loop.settings import LoopSettings
from mppf.measure.mark import design_mark
from mppf.planning.job import load_job
from mppf.sim.plc.link import InProcessPress


class _StationScanner:
    """A scanner station that delivers the design bent ``factor`` times as much (its heights in its own frame),
    in press coordinates and ``scale`` (1e-3: written in metres), with the reference mark beside it."""

    def __init__(self, design_points, job, factor: float, scale: float = 1.0):
        self.design, self.job, self.factor, self.scale = np.asarray(design_points, dtype=float), job, factor, scale

    def _bent(self, points):
        frame = fit_frame(self.design)
        local = frame.to_local(points)
        local[:, 2] *= self.factor
        return self.scale * apply_tf(self.job.tf_press_design, frame.to_world(local))

    folder = None  # the scans are made here (the Scanner protocol)

    def rescan(self, cycle, number, context) -> Path:
        return self.acquire(cycle, context)

    def acquire(self, cycle, context) -> Path:
        path = Path(context.work_dir) / f"station-scan-{cycle}.csv"
        path.parent.mkdir(parents=True, exist_ok=True)
        write_points(path, self._bent(self.design))
        mark = self._bent(design_mark(self.design, self.job)[None])[0]
        Path(str(path) + ".mark.json").write_text(json.dumps({"reference_mark_mm": [float(v) for v in mark]}))
        return path


def _run(tmp_path, planned_plate, plate_id, scanner_of):
    design, flat, press, job = planned_plate
    with History(tmp_path / "h.sqlite") as history, AuditLog(tmp_path / "audit.sqlite") as audit:
        record_plate(history, PlateInputs(design, flat, press, 20.0), job, plate_id=plate_id,
                     work_dir=tmp_path / plate_id, options=LoopOptions(settings=LoopSettings(max_cycles=3)))
        scanner = scanner_of(design.points, load_job(history.cycle(plate_id, 1).job_path))
        with InProcessPress(press, audit=audit) as link:
            return run_loop(history, plate_id, link, scanner), history.cycle(plate_id, 1)


def test_a_badly_formed_plate_stops_the_loop_with_its_verdict(tmp_path, planned_plate):
    result, record = _run(tmp_path, planned_plate, "B1", lambda design, job: _StationScanner(design, job, 4.0))
    assert result.status == "badly_formed" and record.decision == "badly_formed" and record.state == "done"
    assert record.rejected_scans == []  # judged, not refused
    verdict = record.comparison["verdict"]
    assert verdict["kind"] == "out_of_tolerance" and verdict["badly_formed"]
    assert verdict["headline"].startswith("OUT of tolerance: badly formed: only")
    assert record.comparison["badly_formed"]["same_plate"] and record.punch_deviation_mm is not None
    assert len(result.cycles) == 1  # nothing corrected or pressed after it


def test_a_scan_in_other_units_is_refused_and_the_cycle_waits(tmp_path, planned_plate):
    with pytest.raises(GeometryError, match="--units"):
        _run(tmp_path, planned_plate, "M1", lambda design, job: _StationScanner(design, job, 1.0, scale=1e-3))
    with History(tmp_path / "h.sqlite") as history:
        record = history.cycle("M1", 1)
        assert record.state == "pressed" and len(record.rejected_scans) == 1


def test_the_loop_decides_by_the_comparison_verdict():
    from mppf.loop.decide import decide
    from mppf.loop.states import Decision
    from mppf.measure.decision import Figures, Limits, verdict

    settings, limits = LoopSettings(tolerance_mm=2.5, rms_tolerance_mm=1.0), Limits(2.5, 1.0)
    gaps = verdict(Figures(1.0, 0.3, gaps=("0.100 m^2 at u, v = 10, 20 mm (gap 300 mm across)",), n_gaps=1,
                           allowed_gap_mm=100.0), limits)
    assert gaps.kind == "needs_review" and "1 area(s) of the net plate not measured" in gaps.headline
    assert decide([0.3], 1.0, 1, settings, verdict=gaps) == Decision.NEEDS_REVIEW
    covered = verdict(Figures(1.0, 0.3, allowed_gap_mm=100.0), limits)
    assert decide([0.3], 1.0, 1, settings, verdict=covered) == Decision.IN_TOLERANCE
    # out of tolerance with a gap: the loop corrects (what was measured already fails)
    assert decide([1.6], 4.0, 1, settings, verdict=verdict(Figures(4.0, 1.6, n_gaps=1), limits)) == Decision.CONTINUE
    bad = verdict(Figures(40.0, 30.0, badly_formed="only 20 % of the points lie within 25 mm"), limits)
    assert bad.kind == "out_of_tolerance" and bad.badly_formed and bad.reasons[0].startswith("badly formed: only")
    assert decide([30.0], 40.0, 1, settings, verdict=bad) == Decision.BADLY_FORMED
