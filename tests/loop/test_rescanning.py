"""Rescans in the loop with the simulated scanner: a first take that leaves an area unmeasured, its rescan, the
union in tolerance; the overlap guard on its own."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from driver_helpers import HookReporter
from station_helpers import plate_files

from mppf.loop.cycle import run_loop
from mppf.loop.history import History
from mppf.loop.options import LoopOptions, PlateInputs
from mppf.loop.plate import plan_first_cycle, record_plate
from mppf.loop.rescanning import AGREE_FLOOR_MM, AGREE_NOISE, MIN_OVERLAP, overlap_agreement
from mppf.loop.settings import LoopSettings
from mppf.planning.job import load_job
from mppf.model.press import example_press_path, load_press
from mppf.sim.plc.link import InProcessPress
from mppf.sim.shop import SimulatedPlateScanner

# limits the simulated plate meets in its first cycle: coverage alone decides (tested on its own in tests/measure)
SETTINGS = dict(max_cycles=1, margin_mm=0.0, tolerance_mm=60.0, rms_tolerance_mm=30.0)
SEED = 1  # its first take hides a 0.12 m^2 area on the rim; the first rescan measures it


@pytest.fixture(scope="module")
def camber(tmp_path_factory):
    """A 1000 x 640 mm cambered plate, planned: (design, flat, press, job)."""
    from mppf.geometry.read import read_points

    x, y = np.meshgrid(np.linspace(-500.0, 500.0, 26), np.linspace(-320.0, 320.0, 17))
    z = x**2 / (2 * 6000.0) + 1e-7 * x**3 + y**2 / (2 * 20000.0)
    design_path, flat_path = plate_files(tmp_path_factory.mktemp("camber"), "camber",
                                         np.column_stack([x.ravel(), y.ravel(), z.ravel()]))
    design, flat = read_points(design_path), read_points(flat_path)
    press = load_press(example_press_path())
    return design, flat, press, plan_first_cycle(design, flat, press, 20.0, settings=LoopSettings(**SETTINGS))


def _loop(tmp_path, plate, history, rescans=2):
    design, flat, press, job = plate
    if "SIM" not in [p.plate_id for p in history.plates()]:
        record_plate(history, PlateInputs(design, flat, press, 20.0), job, plate_id="SIM", work_dir=tmp_path / "SIM",
                     options=LoopOptions(settings=LoopSettings(**SETTINGS, rescans=rescans)))
    scanner = SimulatedPlateScanner.for_job(press, 20.0, load_job(history.cycle("SIM", 1).job_path), flat.points,
                                            seed=SEED)
    reporter = HookReporter()
    with InProcessPress(press) as link:
        return run_loop(history, "SIM", link, scanner, reporter=reporter), reporter.messages


def test_the_simulated_scanner_rescans_and_the_union_is_in_tolerance(camber, tmp_path):
    with History(tmp_path / "h.sqlite") as history:
        result, messages = _loop(tmp_path, camber, history)
        comparison = history.cycle("SIM", 1).comparison
    assert result.status == "in_tolerance", messages
    assert any("1 area(s) not measured (0.124 m^2 on the rim" in m and "asking for rescan 1 of 2" in m
               for m in messages)
    assert not any("rescan 2" in m for m in messages)  # the union of two scans covers the plate
    scans = comparison["scans"]
    assert [s["rescan"] for s in scans] == [0, 1] and all(s["merged"] for s in scans)
    assert scans[1]["path"].endswith("scan-cycle-01-rescan-1.ply") and all(len(s["sha256"]) == 64 for s in scans)
    assert comparison["n_points"] == sum(s["n_points"] for s in scans) and comparison["coverage"]["complete"]
    assert all(s["agreement"]["agrees"] and s["agreement"]["difference_mm"] < 0.5 for s in scans[1:])


def test_the_overlap_guard():
    rng = np.random.default_rng(1)
    uv = rng.uniform(0.0, 1000.0, (4000, 2))
    shape = 0.002 * uv[:, 0]  # a smooth deviation field: the plate's own error, the same in both scans
    before = shape[:2000] + rng.normal(0.0, 0.3, 2000)

    def union(after):
        dev = np.r_[before, after]
        flags = np.zeros(dev.shape[0], dtype=bool)
        return SimpleNamespace(deviation_mm=dev, is_outlier=flags, is_outside=flags, measured_uv_mm=uv)

    agreed = overlap_agreement(union(shape[2000:] + rng.normal(0.0, 0.3, 2000)), 2000)
    assert agreed.agrees and agreed.overlap > 1000 and 0.2 < agreed.noise_mm < 0.45
    assert agreed.limit_mm == pytest.approx(AGREE_NOISE * agreed.noise_mm + AGREE_FLOOR_MM)
    moved = overlap_agreement(union(shape[2000:] + 5.0 + rng.normal(0.0, 0.3, 2000)), 2000)
    assert not moved.agrees and 4.5 < moved.difference_mm < 5.5 and "moved" not in moved.describe()
    assert "> " in moved.describe()
    # a rescan with hardly any overlap cannot be checked
    far = SimpleNamespace(deviation_mm=np.r_[before, np.zeros(10)], is_outlier=np.zeros(2010, bool),
                          is_outside=np.zeros(2010, bool), measured_uv_mm=np.r_[uv[:2000], uv[:10] + 5000.0])
    lonely = overlap_agreement(far, 2000)
    assert lonely.overlap < MIN_OVERLAP and not lonely.agrees and "cannot be checked" in lonely.describe()


def test_what_a_rescan_is_asked_for():
    from mppf.loop.rescanning import _rescannable
    from mppf.measure.decision import Figures, Limits, verdict

    limits = Limits(2.5, 1.0)
    gaps = dict(gaps=("0.5 m^2 on the rim",), n_gaps=1, allowed_gap_mm=100.0)
    # within the limits, only areas not measured or artefacts in the way: a rescan decides it
    assert _rescannable(verdict(Figures(1.0, 0.4, **gaps), limits))
    assert _rescannable(verdict(Figures(1.0, 0.4, set_aside=3, set_aside_beyond=2, set_aside_max_mm=9.0), limits))
    # out of tolerance with areas not measured: the correction needs the plate there
    assert _rescannable(verdict(Figures(4.0, 1.5, **gaps), limits))
    # a point measured so twice gets another look (only a wall beside it clears it: mppf.measure.outliers)
    assert _rescannable(verdict(Figures(1.0, 0.4, set_aside=3, set_aside_beyond=1, set_aside_max_mm=7.0,
                                        confirmed_beyond=1), limits))
    # out of tolerance, all of it measured; a badly formed plate: no rescan
    assert not _rescannable(verdict(Figures(4.0, 1.5), limits))
    assert not _rescannable(verdict(Figures(40.0, 20.0, badly_formed="this plate, 36.8 mm RMS off", **gaps), limits))
    assert not _rescannable(verdict(Figures(1.0, 0.4), limits)) and not _rescannable(None)


def test_every_rescan_also_asks_for_the_artefact_spots(monkeypatch):
    """A rescan taken for areas not measured while the cycle is out of tolerance asks for the artefact spots too:
    once the areas are measured the union may be within the limits, and then the artefacts decide (P2 seed 2 of
    bench_loop --mode loop: its one rescan went to the gaps alone and 129 spikes were left needing review)."""
    from mppf.loop import rescanning
    from mppf.measure.decision import Figures, Limits, verdict

    monkeypatch.setattr(rescanning, "artefact_spots", lambda comparison, tf: [{"kind": "artefacts", "tf": tf}])
    limits = Limits(2.5, 1.0)
    gaps = dict(gaps=("0.5 m^2 on the rim",), n_gaps=1, allowed_gap_mm=100.0)
    spikes = dict(set_aside=40, set_aside_beyond=30, set_aside_max_mm=45.0)
    for figures in (Figures(4.0, 1.5, **gaps, **spikes), Figures(1.0, 0.4, **spikes), Figures(1.0, 0.4, **gaps,
                                                                                              **spikes)):
        assert rescanning._spots(SimpleNamespace(verdict=verdict(figures, limits)), "tf") == [{"kind": "artefacts",
                                                                                                 "tf": "tf"}]
    # no artefact beyond the tolerance left (or no verdict): only the areas are asked for
    assert rescanning._spots(SimpleNamespace(verdict=verdict(Figures(4.0, 1.5, **gaps), limits)), "tf") == []
    assert rescanning._spots(SimpleNamespace(verdict=None), "tf") == []
