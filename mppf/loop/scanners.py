"""Where the loop's measurements come from: scanners behind the :class:`~mppf.core.scanner.Scanner` protocol.

A scanner delivers, for one press cycle, the path of a point file (PLY, CSV, XYZ...) of
the formed plate's top skin, in any pose. :class:`DirectoryScanner` waits for the file the
operator's 3D scanner (or the person running it) drops into a folder; the simulated
scanner of dry runs (``mppf.sim.shop``) forms and scans a simulated plate instead. The
loop (:mod:`mppf.loop.cycle`) takes either through this one interface; before it waits, it
writes the scan request into the scanner's ``folder`` (:mod:`mppf.loop.scan_request`), and
it takes the scan only with its reference mark (:class:`mppf.loop.marks.MarkedScanner`).
See ``docs/scanner-station.md``.
"""

from __future__ import annotations

import time
from pathlib import Path

from mppf.core.errors import InputError
from mppf.core.scanner import ScanContext
from mppf.core.validate import check_positive
from mppf.geometry.read import READ_SUFFIXES
from mppf.loop.scan_request import scan_name


class DirectoryScanner:
    """Waits for the operator's scan file in a folder.

    A file counts as the scan of the cycle when its suffix is a point format
    (:data:`mppf.geometry.read.READ_SUFFIXES`: ``.ply .csv .txt .xyz .e57 .las .laz``...), it was modified after the cycle was planned
    (``context.since_s``), no earlier cycle of the plate used it, and its size
    stayed the same over two polls (the scanner software finished writing it). When
    several qualify, the newest is taken.

    Parameters
    ----------
    folder : path-like
        Folder the scanner software writes into (must exist).
    timeout_s : float
        Longest wait for the file (s); a shorter one when the context asks (``ScanContext.wait_s``: a rescan).
    poll_s : float
        Interval between looks into the folder.
    """

    def __init__(self, folder, *, timeout_s: float = 1800.0, poll_s: float = 1.0):
        self.folder = Path(folder)
        if not self.folder.is_dir():
            raise InputError(
                f"scan folder {self.folder} does not exist or is not a folder",
                hint="give the folder the scanner software writes into, or --scanner sim for a dry run",
            )
        self.timeout_s = check_positive("the scan wait timeout (--scan-timeout)", timeout_s, unit="s")
        self.poll_s = check_positive("the scan poll interval", poll_s, unit="s")

    def _candidates(self, context: ScanContext) -> dict[Path, int]:
        used = {str(Path(p).resolve()) for p in context.used_paths}
        found = {}
        for path in self.folder.iterdir():
            if path.suffix.lower() not in READ_SUFFIXES or not path.is_file():
                continue
            try:
                stat = path.stat()
            except OSError:  # removed while we looked
                continue
            if stat.st_mtime + 1.0 < context.since_s or str(path.resolve()) in used:
                continue
            found[path] = stat.st_size
        return found

    def acquire(self, cycle: int, context: ScanContext) -> Path:
        """Wait for a new, complete scan file; return its path."""
        return self._wait(cycle, context, "the scan file", f"scan {cycle}")

    def rescan(self, cycle: int, number: int, context: ScanContext) -> Path:
        """Wait for the ``number``-th rescan of the cycle: a new, complete scan file (not one of ``context.used_paths``,
        which hold the cycle's first scan and earlier rescans); in the first scan's frame (the station's business)."""
        expected = (self.folder / scan_name(context.plate_id, cycle, number)).resolve()
        return self._wait(cycle, context, f"rescan {number}", f"scan {cycle} rescan {number}", expected)

    def _wait(self, cycle: int, context: ScanContext, what: str, task: str, expected: Path | None = None) -> Path:
        timeout_s = self.timeout_s if context.wait_s is None else min(self.timeout_s, context.wait_s)
        context.reporter.info(f"cycle {cycle}: waiting for {what} in {self.folder} (up to {timeout_s:.0f} s)")
        context.reporter.start(f"waiting for {task}", total=timeout_s)
        start = time.monotonic()
        previous: dict[Path, int] = {}
        try:
            while True:
                current = self._candidates(context)
                stable = [p for p, size in current.items() if size > 0 and previous.get(p) == size]
                if stable:  # the file the request named, else the newest
                    named = [p for p in stable if p.resolve() == expected]
                    return named[0] if named else max(stable, key=lambda p: p.stat().st_mtime)
                previous = current
                waited = time.monotonic() - start
                if waited >= timeout_s:
                    raise InputError(
                        f"no new scan file appeared in {self.folder} within {timeout_s:.0f} s "
                        f"for {task.replace('scan ', 'cycle ', 1)} of plate {context.plate_id}",
                        hint="save the scan there (PLY or CSV) and run 'mppf loop --resume' to go on",
                    )
                context.reporter.update(waited)
                time.sleep(self.poll_s)
        finally:
            context.reporter.finish()
