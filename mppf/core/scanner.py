"""The one interface of "a scanner": what the loop needs to get a measurement of the formed plate.

The loop (:mod:`mppf.loop.cycle`) takes a :class:`Scanner`; :class:`mppf.loop.scanners.DirectoryScanner`
waits for the files of a real scanner station, the simulated plate and scanner of
``mppf.sim.shop`` make one.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np

from mppf.core.progress import NULL_REPORTER, Reporter


@dataclass(frozen=True, eq=False)
class PressedStep:
    """One press step of a cycle as the press did it (what a simulated plate must be pressed with).

    Attributes
    ----------
    cycle, step : int
        The cycle and its step (1-based).
    upper_mm, lower_mm : (rows, cols) float
        Tip heights read back from the press after the step (for an interrupted step:
        its setpoints, which the tips were moving towards when the motion stopped),
        parking heights where inactive.
    active : (rows, cols) bool
        Punches acting on the plate.
    complete : bool
        False: the step was interrupted during its motion (the master died or was
        stopped; the PLC halted the punches part of the way to ``upper_mm, lower_mm``).
    """

    cycle: int
    step: int
    upper_mm: np.ndarray
    lower_mm: np.ndarray
    active: np.ndarray
    complete: bool = True


@dataclass(frozen=True)
class ScanContext:
    """What a scanner may want to know about the cycle to measure.

    Attributes
    ----------
    plate_id : str
    work_dir : Path
        The plate's work folder (job files, simulated scans).
    since_s : float
        Unix time (s) when the cycle was planned: a scan file must be newer.
    used_paths : tuple of str
        Scan files already used by earlier cycles of this plate (never taken again).
    upper_mm, lower_mm : (rows, cols) float
        Tip heights of the last press step of the cycle as read back from the press
        (its setpoints when the read-back was lost in a crash), parking heights where
        inactive.
    active : (rows, cols) bool
        Punches acting on the plate in that step.
    steps : tuple of PressedStep
        Every step of the cycle the press started, in order: the completed ones with
        their read-back tips, an interrupted one last (``complete=False``).
    reporter : Reporter
        Progress of a long wait.
    regions : tuple of dict
        A rescan: the areas it is asked for (the rescan request's ``regions``: ``kind``,
        ``corners_press_mm`` where the press pose is known, ...); empty for a cycle's first scan.
    wait_s : float or None
        The longest wait for this file (s) when the loop wants a shorter one than the scanner's own
        (a rescan: ``LoopSettings.rescan_timeout_s``); None: the scanner's own timeout.
    """

    plate_id: str
    work_dir: Path
    since_s: float
    upper_mm: np.ndarray
    lower_mm: np.ndarray
    active: np.ndarray
    used_paths: tuple[str, ...] = ()
    steps: tuple[PressedStep, ...] = ()
    reporter: Reporter = field(default=NULL_REPORTER)
    regions: tuple = ()
    wait_s: float | None = None


@runtime_checkable
class Scanner(Protocol):
    """A source of scans of the formed plate.

    Attributes
    ----------
    folder : Path or None
        The scanner station's folder: where its scan files arrive and the loop posts its scan
        requests (:mod:`mppf.loop.scan_request`), and whether a missing reference mark is worth
        waiting for. None for a scanner that makes its scans itself (the simulated plate's): the
        requests then go to the plate's work folder.
    """

    folder: Path | None

    def acquire(self, cycle: int, context: ScanContext) -> Path:
        """Return the path of the scan of the plate after press cycle ``cycle``.

        Raises
        ------
        InputError
            No usable scan arrived (the message says where it was expected).
        """

    def rescan(self, cycle: int, number: int, context: ScanContext) -> Path:
        """Return the path of the ``number``-th rescan (1, 2, ...) of the plate after cycle ``cycle``.

        The rescan is in the frame of the cycle's first scan (the plate not moved);
        ``context.regions`` lists the areas asked for, ``context.used_paths`` the scans taken
        before (never returned again).

        Raises
        ------
        InputError
            No rescan arrived in the wait (``context.wait_s``).
        """
