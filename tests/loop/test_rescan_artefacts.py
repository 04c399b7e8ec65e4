"""The loop rescans where the first scan's spikes lie beyond the tolerance; the rescan clears them: in tolerance.

An in-process fixed station scans the plate as designed (its top skin on a jittered 20 mm
grid, 0.3 mm noise) with 1 % spikes 5 - 50 mm off, each take its own; the first take's spikes
make the cycle need review (issue 13), the rescan re-measures their spots within the
tolerance and the union is in tolerance, the cleared points reported.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mppf.sim.plc.link import InProcessPress
from scan_station import write_ply
from station_helpers import asymmetric_points, plate_files, request_keeper

from mppf.core.transform import apply_tf
from mppf.loop.cycle import run_loop
from mppf.loop.history import History
from mppf.loop.options import LoopOptions, PlateInputs
from mppf.loop.plate import plan_first_cycle, record_plate
from mppf.loop.settings import LoopSettings
from mppf.model.press import example_press_path, load_press
from mppf.planning.job import load_job

SETTINGS = {"max_cycles": 1, "margin_mm": 0.0, "mark_settle_s": 0.0}  # the station writes no mark; the plate needs none
THICKNESS_MM = 20.0


def _mid(x, y):
    """The mid-surface of :func:`station_helpers.asymmetric_points`."""
    return x**2 / (2 * 6000.0) + 1e-7 * x**3 + 60.0 * np.exp(-((x - 350.0) ** 2 + (y - 180.0) ** 2) / (2 * 220.0**2))


class SpikyStation:
    """A fixed station in process: the plate as designed, each take with its own noise and spikes, one frame."""

    folder = None  # no station folder (the Scanner protocol)

    def __init__(self, job_path: Path, spikes: float = 0.01):
        self.job_path, self.spikes, self.takes = job_path, spikes, []

    def acquire(self, cycle: int, context) -> Path:
        return self._take(context.work_dir / f"art-cycle-{cycle:02d}.ply", seed=10 * cycle)

    def rescan(self, cycle: int, number: int, context) -> Path:
        return self._take(context.work_dir / f"art-cycle-{cycle:02d}-rescan-{number}.ply", seed=10 * cycle + number)

    def _take(self, path: Path, seed: int) -> Path:
        rng = np.random.default_rng(seed)
        x, y = np.meshgrid(np.arange(-690.0, 691.0, 20.0), np.arange(-440.0, 441.0, 20.0))
        xy = np.clip(np.column_stack([x.ravel(), y.ravel()]) + rng.uniform(-10.0, 10.0, (x.size, 2)), -699.0, 699.0)
        xy[:, 1] = np.clip(xy[:, 1], -449.0, 449.0)
        mid = np.column_stack([xy, _mid(xy[:, 0], xy[:, 1])])
        step = 1e-3  # the normal from the mid-surface's slope, turned to press coordinates and up
        slope = np.column_stack([(_mid(xy[:, 0] + step, xy[:, 1]) - mid[:, 2]) / step,
                                 (_mid(xy[:, 0], xy[:, 1] + step) - mid[:, 2]) / step])
        normal = np.column_stack([-slope, np.ones(len(xy))])
        normal /= np.linalg.norm(normal, axis=1)[:, None]
        tf = np.asarray(load_job(self.job_path).tf_press_design, dtype=float)
        normal = normal @ tf[:3, :3].T
        normal *= np.sign(normal[:, 2])[:, None]
        top = apply_tf(tf, mid) + THICKNESS_MM / 2.0 * normal
        off = rng.normal(0.0, 0.3, len(top))
        hit = rng.random(len(top)) < self.spikes
        off[hit] += rng.choice([-1.0, 1.0], hit.sum()) * rng.uniform(5.0, 50.0, hit.sum())
        path.parent.mkdir(parents=True, exist_ok=True)
        write_ply(path, top + off[:, None] * normal)
        self.takes.append(path)
        return path


@pytest.fixture(scope="module")
def bump(tmp_path_factory):
    from mppf.geometry.read import read_points

    design_path, flat_path = plate_files(tmp_path_factory.mktemp("art"), "bump", asymmetric_points())
    design, flat = read_points(design_path), read_points(flat_path)
    press = load_press(example_press_path())
    return design, flat, press, plan_first_cycle(design, flat, press, THICKNESS_MM, settings=LoopSettings(**SETTINGS))


def _loop(tmp_path, plate, rescans):
    design, flat, press, job = plate
    reporter, requests = request_keeper()
    with History(tmp_path / "h.sqlite") as history:
        record_plate(history, PlateInputs(design, flat, press, THICKNESS_MM), job, plate_id="ART",
                     work_dir=tmp_path / "ART", options=LoopOptions(settings=LoopSettings(**SETTINGS, rescans=rescans)))
        station = SpikyStation(history.cycle("ART", 1).job_path)
        with InProcessPress(press) as link:
            result = run_loop(history, "ART", link, station, reporter=reporter)
        comparison = history.cycle("ART", 1).comparison
    return result, reporter.messages, comparison, requests


def test_the_rescan_clears_the_first_scans_spikes(bump, tmp_path):
    result, messages, comparison, requests = _loop(tmp_path, bump, rescans=2)
    assert result.status == "in_tolerance", messages
    asked = [m for m in messages if "asking for rescan 1 of 2" in m]
    assert len(asked) == 1 and "set-aside point(s) beyond the tolerance at" in asked[0]
    # the request named the spots of the spikes (kind "artefacts"), the largest first
    request = requests["ART-cycle-01-rescan-1.scan-request.json"]
    spots = [r for r in request["regions"] if r["kind"] == "artefacts"]
    assert spots and request["artefact_spots"] == len(spots) and all(len(s["corners_press_mm"]) == 4 for s in spots)
    assert [s["max_abs_mm"] for s in spots] == sorted((s["max_abs_mm"] for s in spots), reverse=True)
    assert all(s["max_abs_mm"] > 2.5 and s["count"] >= 1 for s in spots)
    # the union: every spike beyond the tolerance cleared by the other take, still reported
    aside = comparison["set_aside"]
    assert [s["rescan"] for s in comparison["scans"]] == [0, 1] and all(s["merged"] for s in comparison["scans"])
    assert aside["beyond_tolerance"] == 0 and aside["cleared"] > 20 and aside["confirmed"] == 0
    assert set(aside["cleared_by"]) == {"0", "1"} and comparison["verdict"]["set_aside_cleared"] == aside["cleared"]
    assert "cleared by the first scan (" in comparison["headline"] and "rescan 1 (" in comparison["headline"]


def test_without_rescans_the_spikes_need_review(bump, tmp_path):
    result, messages, comparison, _ = _loop(tmp_path, bump, rescans=0)
    assert result.status == "needs_review", messages
    assert comparison["set_aside"]["beyond_tolerance"] > 20 and comparison["set_aside"]["cleared"] == 0
    assert not any("asking for rescan" in m for m in messages)
