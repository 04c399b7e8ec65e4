"""Plain progress lines (mppf.core.progress.LineReporter): timestamps, heartbeats during silent work, closing."""

from __future__ import annotations

import re
import threading
import time

from mppf.core.progress import LineReporter

STAMP = re.compile(r"^\d\d:\d\d:\d\d ")


class Lines:
    def __init__(self):
        self.lines: list[str] = []
        self._lock = threading.Lock()

    def __call__(self, line: str) -> None:
        with self._lock:
            self.lines.append(line)


def test_line_reporter_prints_timestamped_start_progress_and_end_lines():
    out = Lines()
    reporter = LineReporter(out, interval_s=0.0)
    reporter.start("motion", total=4)
    for _ in range(4):
        reporter.advance()
    reporter.finish()
    reporter.close()
    assert all(STAMP.match(line) for line in out.lines)
    assert out.lines[0].endswith("motion: started (4 to do)") and "motion: done in" in out.lines[-1]
    assert any("motion: 4/4 (100 %)" in line for line in out.lines)


def test_line_reporter_beats_during_silent_work_and_stops_when_closed():
    out = Lines()
    reporter = LineReporter(out, interval_s=0.1)
    reporter.info("comparing the scan")  # a step without progress of its own
    time.sleep(0.55)
    reporter.close()
    beats = [line for line in out.lines if "still working" in line and "comparing the scan" in line]
    assert len(beats) >= 3  # one per interval of silence
    time.sleep(0.25)
    assert len(out.lines) == 1 + len(beats)  # closed: no more lines


def test_line_reporter_heartbeat_of_a_task_without_advances():
    out = Lines()
    reporter = LineReporter(out, interval_s=0.1)
    reporter.start("waiting for the scan")
    time.sleep(0.35)
    reporter.finish()
    reporter.close()
    assert sum("waiting for the scan: working" in line for line in out.lines) >= 2


def test_line_reporter_keeps_beating_after_a_task_until_closed():
    out = Lines()
    reporter = LineReporter(out, interval_s=0.1)
    reporter.start("motion")
    reporter.finish()
    time.sleep(0.35)  # e.g. the compare after the motion, which reports nothing itself
    reporter.close()
    assert any("still working" in line and "since: motion done" in line for line in out.lines)
