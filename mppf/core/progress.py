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
