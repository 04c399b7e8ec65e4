"""The scan folder: the operator's scan file, taken when it is new and complete."""

from __future__ import annotations

import os
import threading
import time

import numpy as np
import pytest

from mppf.core.errors import InputError
from mppf.core.scanner import ScanContext
from mppf.loop.scanners import DirectoryScanner


def _context(tmp_path, since_s, used=()):
    grid = np.zeros((2, 2))
    return ScanContext(plate_id="P", work_dir=tmp_path, since_s=since_s, upper_mm=grid, lower_mm=grid,
                       active=grid.astype(bool), used_paths=tuple(str(p) for p in used))


def test_directory_scanner_takes_the_new_complete_file(tmp_path):
    folder = tmp_path / "scans"
    folder.mkdir()
    old = folder / "old.csv"
    old.write_text("0,0,0\n")
    os.utime(old, (time.time() - 3600, time.time() - 3600))  # from before the cycle
    used = folder / "used.csv"
    used.write_text("1,1,1\n")  # an earlier cycle's scan
    (folder / "notes.txt.bak").write_text("not a scan")
    scanner = DirectoryScanner(folder, timeout_s=10, poll_s=0.05)
    target = folder / "cycle2.ply"

    def operator_saves_scan():
        time.sleep(0.3)
        target.write_bytes(b"x" * 100)

    thread = threading.Thread(target=operator_saves_scan)
    thread.start()
    try:
        got = scanner.acquire(2, _context(tmp_path, time.time() - 1, used=[used]))
    finally:
        thread.join()
    assert got == target


def test_directory_scanner_times_out_with_a_clear_error(tmp_path):
    scanner = DirectoryScanner(tmp_path, timeout_s=0.2, poll_s=0.05)
    with pytest.raises(InputError, match="no new scan file appeared") as info:
        scanner.acquire(1, _context(tmp_path, time.time()))
    assert "--resume" in info.value.hint


def test_a_rescan_waits_the_shorter_wait_the_loop_asks_for(tmp_path):
    import dataclasses

    scanner = DirectoryScanner(tmp_path, timeout_s=30.0, poll_s=0.05)
    context = dataclasses.replace(_context(tmp_path, time.time()), wait_s=0.3)
    start = time.monotonic()
    with pytest.raises(InputError, match="within 0 s|within 1 s") as info:  # 0.3 s, printed to the second
        scanner.rescan(1, 1, context)
    assert time.monotonic() - start < 5.0 and "rescan 1" in info.value.message
    # never longer than the scanner's own timeout
    short = DirectoryScanner(tmp_path, timeout_s=0.2, poll_s=0.05)
    start = time.monotonic()
    with pytest.raises(InputError):
        short.rescan(1, 1, dataclasses.replace(context, wait_s=60.0))
    assert time.monotonic() - start < 5.0


def test_directory_scanner_needs_a_folder(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        DirectoryScanner(tmp_path / "missing")


def test_directory_scanner_needs_positive_waits(tmp_path):
    with pytest.raises(InputError, match=r"scan wait timeout \(--scan-timeout\) must be above 0 s, got 0 s"):
        DirectoryScanner(tmp_path, timeout_s=0)
