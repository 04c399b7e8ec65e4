"""Helpers of the panel tests: a job with a plate layout, a history holding a plate's loop."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from mppf.loop.history import History
from mppf.loop.options import PlateFiles
from mppf.loop.states import Decision
from mppf.model.job import Job
from mppf.model.job_parts import PlateLayout, StepStrokes
from mppf.model.press import example_press_path, load_press
from mppf.planning.job import save_job

THICKNESS_MM = 20.0
CUT_MM = ((-1200.0, -800.0), (1300.0, -800.0), (1300.0, 700.0), (-1200.0, 700.0))
"""The plate as cut (a rectangle, counter-clockwise) of :func:`layout_job`."""
MARGIN_MM = 100.0


def rectangle(corners, points_per_side: int = 1) -> np.ndarray:
    """A closed outline through ``corners``, ``points_per_side`` points a side (the corner and collinear ones)."""
    corners = np.asarray(corners, dtype=float)
    out = []
    for a, b in zip(corners, np.roll(corners, -1, axis=0)):
        for t in np.linspace(0.0, 1.0, points_per_side, endpoint=False):
            out.append(a + t * (b - a))
    return np.array(out)


def layout_job(press=None, n_steps: int = 1) -> Job:
    """A job of the example press with a plate layout: a rectangle cut with a 100 mm margin.

    Strokes: lower tips 0..30 mm over the punches under the plate, upper tips the plate
    thickness above them; step k at k / n_steps of the way.
    """
    press = press or load_press(example_press_path())
    x, y = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    (x0, y0), _, (x1, y1), _ = CUT_MM
    active = (x > x0) & (x < x1) & (y > y0) & (y < y1)
    lower = 30.0 * ((x - x0) / (x1 - x0)) ** 2
    steps = [StepStrokes(np.where(active, THICKNESS_MM + lower * k / n_steps, np.nan),
                         np.where(active, lower * k / n_steps, np.nan), active) for k in range(1, n_steps + 1)]
    net = np.array(CUT_MM) + np.array([[1, 1], [-1, 1], [-1, -1], [1, -1]]) * MARGIN_MM
    layout = PlateLayout(outline_mm=rectangle(CUT_MM, 4), net_outline_mm=rectangle(net, 3), margin_mm=MARGIN_MM)
    return Job(press=press, thickness_mm=THICKNESS_MM, steps=steps, layout=layout)


def record_loop(history_path: Path, job: Job, work_dir: Path, *, plate_id: str = "B12-P3",
                measured: int = 1) -> History:
    """A history with one plate: ``measured`` cycles pressed, scanned, compared and corrected, the next planned.

    Cycle k's deviation at the punches is ``(9 - 3 k) mm`` times a saddle (largest at the
    corners), out of the 2.5 mm tolerance; every decision is "continue".
    """
    work_dir.mkdir(parents=True, exist_ok=True)
    history = History(history_path)
    history.create_plate(plate_id, PlateFiles("design.csv", "0" * 64, "flat.csv", "1" * 64),
                         thickness_mm=job.thickness_mm, press=job.press.to_dict(),
                         settings={"loop": {"tolerance_mm": 2.5, "rms_tolerance_mm": 1.0}, "work_dir": str(work_dir),
                                   "plc": None})
    path = save_job(job, work_dir / "cycle-01.job.json")
    history.add_cycle(plate_id, 1, job_path=path, job_sha256=job.sha256(), steps=job.steps)
    x, y = np.meshgrid(np.linspace(-1, 1, job.press.cols), np.linspace(-1, 1, job.press.rows))
    for k in range(1, measured + 1):
        deviation = (9.0 - 3.0 * k) * x * y
        _press_and_compare(history, plate_id, k, job, deviation)
        path = save_job(job, work_dir / f"cycle-{k + 1:02d}.job.json")
        history.add_cycle(plate_id, k + 1, job_path=path, job_sha256=job.sha256(), steps=job.steps, gain=0.8,
                          correction={"gain": None, "applied_mm": (-0.8 * deviation).round(3).tolist(),
                                      "clipped_punches": 2, "notes": ["model step"]},
                          previous_decision=Decision.CONTINUE)
    return history


def _press_and_compare(history: History, plate_id: str, cycle: int, job: Job, deviation: np.ndarray) -> None:
    for step, strokes in enumerate(job.steps, start=1):
        upper, lower = strokes.setpoints_mm(job.press)
        history.mark_step_started(plate_id, cycle, step)
        history.mark_step_done(plate_id, cycle, step, {"sequence": step, "max_error_mm": 0.01, "duration_s": 1.0,
                                                       "actual_upper_mm": upper.tolist(),
                                                       "actual_lower_mm": lower.tolist()})
    history.mark_pressed(plate_id, cycle)
    history.mark_scanned(plate_id, cycle, f"scan-{cycle}.ply", "2" * 64)
    rms = float(np.sqrt(np.mean(deviation ** 2)))
    history.mark_compared(plate_id, cycle, rms_mm=rms, max_abs_mm=float(np.abs(deviation).max()), within_pct=40.0,
                          punch_deviation_mm=deviation, comparison={"rms_mm": rms}, decision=Decision.CONTINUE)


def wait_until(predicate, timeout_s: float = 10.0, what: str = "the condition", poll_s: float = 0.05):
    """``predicate()``'s first true value, polled every ``poll_s`` s; AssertionError naming ``what`` after ``timeout_s`` s."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(poll_s)
    raise AssertionError(f"{what}: not within {timeout_s} s")
