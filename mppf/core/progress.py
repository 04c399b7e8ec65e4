"""One replaceable progress reporter for long operations.

Library code reports progress through a :class:`Reporter`; the command line passes a
terminal implementation (rich progress bars), tests and library users the silent
:data:`NULL_REPORTER`.
"""

from __future__ import annotations

from typing import Protocol


class Reporter(Protocol):
    """Receives progress of long operations and short status lines."""

    def start(self, task: str, total: float | None = None) -> None:
        """A new task begins; ``total`` units of work, or None when unknown."""

    def advance(self, amount: float = 1.0) -> None:
        """``amount`` more units of the current task are done."""

    def update(self, completed: float) -> None:
        """The current task has ``completed`` units done (absolute)."""

    def finish(self) -> None:
        """The current task is over."""

    def info(self, message: str) -> None:
        """A one-line status message for the operator."""


class NullReporter:
    """A reporter that says nothing."""

    def start(self, task: str, total: float | None = None) -> None:
        pass

    def advance(self, amount: float = 1.0) -> None:
        pass

    def update(self, completed: float) -> None:
        pass

    def finish(self) -> None:
        pass

    def info(self, message: str) -> None:
        pass


NULL_REPORTER = NullReporter()


HEARTBEAT_S = 5.0
"""Longest silence of a :class:`LineReporter` while work goes on (s): a log never waits longer for a line."""


def _clock() -> str:
    import time

    return time.strftime("%H:%M:%S")


class LineReporter:
    """A reporter for logs and pipes: plain timestamped lines, never a progress bar.

    Each task prints a line when it starts and when it ends; while it runs, and after each
    status line, a heartbeat thread prints where the work stands whenever nothing was
    printed for ``interval_s`` (default :data:`HEARTBEAT_S`), so a log shows a line at least
    every 5 s during long work (a motion, a compare, a correction). :meth:`close` ends the
    heartbeat.

    Parameters
    ----------
    write : callable
        ``write(line)`` prints one line (without its newline), e.g. to stderr.
    interval_s : float
        Longest silence while work goes on (s).
    """

    def __init__(self, write, interval_s: float = HEARTBEAT_S):
        import threading

        self._write = write
        self._interval_s = float(interval_s)
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._closed = False
        self._thread = None
        self._task: str | None = None
        self._total: float | None = None
        self._done = 0.0
        self._since = 0.0
        self._last_line = 0.0

    # -- Reporter -----------------------------------------------------------------------

    def start(self, task: str, total: float | None = None) -> None:
        self.finish()
        with self._lock:
            self._task, self._total, self._done = str(task), total, 0.0
            self._since = self._now()
        self._line(f"{task}: started" + (f" ({total:g} to do)" if total else ""))
        self._ensure_thread()

    def advance(self, amount: float = 1.0) -> None:
        with self._lock:
            self._done += float(amount)
        self._maybe_line()

    def update(self, completed: float) -> None:
        with self._lock:
            self._done = float(completed)
        self._maybe_line()

    def finish(self) -> None:
        with self._lock:
            task, self._task = self._task, None
            elapsed = self._now() - self._since
            if task is not None:  # what follows (a compare, a correction) beats as "since: TASK done"
                self._since, self._status = self._now(), f"{task} done"
        if task is not None:
            self._line(f"{task}: done in {elapsed:.1f} s")

    def abandon(self, why: str) -> None:
        """End the task without calling it done (a cancelled or failed motion): ``TASK: WHY after N s``."""
        with self._lock:
            task, self._task = self._task, None
            elapsed = self._now() - self._since
            if task is not None:
                self._since, self._status = self._now(), f"{task} {why}"
        if task is not None:
            self._line(f"{task}: {why} after {elapsed:.1f} s")

    def info(self, message: str) -> None:
        with self._lock:
            if self._task is None:  # a step without a task of its own: its heartbeat names this line
                self._since, self._status = self._now(), str(message)
        self._line(str(message))
        self._ensure_thread()

    def close(self) -> None:
        """Stop the heartbeat (the current task, if any, is left without its end line)."""
        self._closed = True
        self._wake.set()

    # -- internals ----------------------------------------------------------------------

    _status: str | None = None

    @staticmethod
    def _now() -> float:
        import time

        return time.monotonic()

    def _state(self) -> str | None:
        with self._lock:
            elapsed = self._now() - self._since
            if self._task is not None:
                if self._total:
                    return (f"{self._task}: {self._done:g}/{self._total:g} "
                            f"({100.0 * self._done / self._total:.0f} %), {elapsed:.0f} s")
                return f"{self._task}: working, {elapsed:.0f} s"
            if self._status is not None:
                return f"still working ({elapsed:.0f} s since: {self._status})"
            return None

    def _line(self, text: str) -> None:
        self._last_line = self._now()
        self._write(f"{_clock()} {text}")

    def _maybe_line(self) -> None:
        if self._now() - self._last_line >= self._interval_s:
            state = self._state()
            if state is not None:
                self._line(state)

    def _ensure_thread(self) -> None:
        import threading

        if self._thread is None and not self._closed:
            self._thread = threading.Thread(target=self._beat, name="mppf-heartbeat", daemon=True)
            self._thread.start()

    def _beat(self) -> None:
        while not self._closed:
            self._wake.wait(max(0.05, self._interval_s - (self._now() - self._last_line)))
            if self._closed:
                return
            self._maybe_line()
