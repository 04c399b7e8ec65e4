"""The scanner protocol (mppf.core.scanner) declares what the loop uses, and every scanner has it."""

from __future__ import annotations

import numpy as np
from driver_helpers import small_press

from mppf.core.scanner import Scanner
from mppf.loop.marks import MarkedScanner
from mppf.loop.scanners import DirectoryScanner
from mppf.sim.shop import SimulatedPlateScanner

OUTLINE = np.array([[-1000.0, -500.0], [1000.0, -500.0], [1000.0, 500.0], [-1000.0, 500.0]])


def test_the_scanners_have_a_folder_and_rescan(tmp_path):
    station = DirectoryScanner(tmp_path, timeout_s=1.0, poll_s=0.1)
    simulated = SimulatedPlateScanner(small_press(), 20.0, OUTLINE, plate_options={"grid_spacing_mm": 150.0})
    marked = MarkedScanner(station, need=lambda: None, plausible=lambda path: True, settle_s=0.1, timeout_s=0.1)
    for scanner in (station, simulated, marked):
        assert isinstance(scanner, Scanner), type(scanner).__name__
    assert station.folder == tmp_path and marked.folder == tmp_path and simulated.folder is None
    assert not isinstance(object(), Scanner)  # the check can fail
