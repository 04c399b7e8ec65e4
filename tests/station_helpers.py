"""Helpers for the scanner-station tests: two small plates and the outside station process (tests/scan_station.py)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

STATION = Path(__file__).with_name("scan_station.py")


def symmetric_points() -> np.ndarray:
    """A 1400 x 900 mm doubly curved bowl: the same under its half turn (it needs the reference mark)."""
    x, y = np.meshgrid(np.linspace(-700.0, 700.0, 36), np.linspace(-450.0, 450.0, 24))
    z = x**2 / (2 * 6000.0) + y**2 / (2 * 15000.0)
    return np.column_stack([x.ravel(), y.ravel(), z.ravel()])


def asymmetric_points() -> np.ndarray:
    """The same size, a cubic camber and a bump near one corner: its half turn misfits it by about 9 mm."""
    x, y = np.meshgrid(np.linspace(-700.0, 700.0, 36), np.linspace(-450.0, 450.0, 24))
    z = x**2 / (2 * 6000.0) + 1e-7 * x**3 + 60.0 * np.exp(-((x - 350.0) ** 2 + (y - 180.0) ** 2) / (2 * 220.0**2))
    return np.column_stack([x.ravel(), y.ravel(), z.ravel()])


def request_keeper():
    """A reporter that keeps every scan request the loop announces, read when announced (the loop withdraws it
    once the scan is taken): ``(reporter, {request file name: its document})``."""
    from driver_helpers import HookReporter

    requests: dict[str, dict] = {}

    def keep(message):
        if "scan request" in message:
            path = Path(message.split("scan request ")[1].split(":")[0])
            requests[path.name] = json.loads(path.read_text())

    return HookReporter(on_info=keep), requests


def plate_files(folder: Path, name: str, points: np.ndarray) -> tuple[Path, Path]:
    """The design and its unfolded flat as CSV files in ``folder``."""
    from mppf.geometry.unfold import unfold
    from mppf.geometry.write import write_points

    folder.mkdir(parents=True, exist_ok=True)
    return (write_points(folder / f"{name}.csv", points),
            write_points(folder / f"{name}.flat.csv", unfold(points).flat))


def planned_plate(folder: Path, name: str, points: np.ndarray, settings) -> tuple:
    """A small plate written as files, read back and planned for its first cycle: (design, flat, press, job)."""
    from mppf.geometry.read import read_points
    from mppf.loop.plate import plan_first_cycle
    from mppf.model.press import example_press_path, load_press

    design_path, flat_path = plate_files(folder, name, points)
    design, flat = read_points(design_path), read_points(flat_path)
    press = load_press(example_press_path())
    return design, flat, press, plan_first_cycle(design, flat, press, 20.0, settings=settings)


def start_station(folder: Path, design: Path, mode: str, *, delay_s: float = 2.0, bend: float = 1.0,
                  scale: float = 1.0) -> subprocess.Popen:
    """The outside scanner station, watching ``folder`` (see tests/scan_station.py)."""
    return subprocess.Popen([sys.executable, str(STATION), str(folder), str(design), "--mode", mode,
                             "--delay", str(delay_s), "--bend", str(bend), "--scale", str(scale)],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def station_log(station: subprocess.Popen, timeout_s: float = 30.0) -> list[str]:
    """The station's lines, once it ended (killed after ``timeout_s``)."""
    try:
        out, _ = station.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        station.kill()
        out, _ = station.communicate()
    return out.splitlines()
