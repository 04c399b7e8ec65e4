"""Shared pieces of the command line: consoles, JSON output, progress bars, options."""

from __future__ import annotations

import json
import math

import click
import numpy as np
from rich.console import Console, ConsoleDimensions
from rich.progress import BarColumn, Progress, TaskProgressColumn, TextColumn, TimeElapsedColumn

PIPE_WIDTH = 100_000
"""Line width when the output is not a terminal: a log or a pipe gets whole lines, never hard-wrapped."""


class LogFriendlyConsole(Console):
    """A rich console that wraps lines only on a terminal.

    Written to a file or a pipe (a log, a test's captured stream), rich would wrap every
    line at 80 columns, splitting paths and plate ids; here the width is then
    :data:`PIPE_WIDTH`, so each message stays on one line. The check is made at each
    print, so a console created before its stream was redirected still does the right thing.
    """

    @property
    def size(self) -> ConsoleDimensions:
        size = super().size
        return size if self.is_terminal else ConsoleDimensions(PIPE_WIDTH, size.height)


console = LogFriendlyConsole(highlight=False)
err_console = LogFriendlyConsole(stderr=True, highlight=False)

units_option = click.option(
    "--units",
    type=click.Choice(["mm", "m"]),
    default="mm",
    show_default=True,
    help="Length unit of the input point files (results are always in mm).",
)

scale_option = click.option(
    "--scale",
    type=click.FloatRange(min=0.0, min_open=True),
    default=1.0,
    show_default=True,
    help="Model scale of the input files: coordinates are multiplied by it (31.6 for a 1:31.6 model).",
)


def _jsonable(value):
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, (np.bool_,)):
        return bool(value)
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if math.isfinite(value) else None
    return value


def print_json(obj) -> None:
    """Print ``obj`` as JSON on stdout (numpy values converted, NaN as null)."""
    click.echo(json.dumps(_jsonable(obj), indent=2))


class RichReporter:
    """A :class:`mppf.core.progress.Reporter` drawing rich progress bars on stderr."""

    def __init__(self, enabled: bool = True):
        self._enabled = enabled
        self._progress: Progress | None = None
        self._task = None

    def start(self, task: str, total: float | None = None) -> None:
        self.finish()
        if not self._enabled:
            return
        self._progress = Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            TaskProgressColumn(),
            TimeElapsedColumn(),
            console=err_console,
            transient=False,
        )
        self._progress.start()
        self._task = self._progress.add_task(task, total=total)

    def advance(self, amount: float = 1.0) -> None:
        if self._progress is not None:
            self._progress.advance(self._task, amount)

    def update(self, completed: float) -> None:
        if self._progress is not None:
            self._progress.update(self._task, completed=completed)

    def finish(self) -> None:
        if self._progress is not None:
            self._progress.stop()
            self._progress = None

    def info(self, message: str) -> None:
        if self._enabled:
            err_console.print(message)


PICTURE_SUFFIXES = (".png", ".pdf", ".svg")
"""Picture files the ``--plot`` options write."""


def check_output_path(path, what: str, suffixes=None, kind: str = "file"):
    """Refuse an output path that cannot be written, before any work is done.

    Parameters
    ----------
    path : str or Path
    what : str
        What the file is, for the message (e.g. ``"the job file"``).
    suffixes : sequence of str, optional
        Accepted suffixes (lower case, with the dot); any when omitted.
    kind : str
        What the suffix names, for the message ("point file", "picture").

    Returns
    -------
    Path

    Raises
    ------
    InputError
        Unknown suffix, a folder that does not exist or cannot be written, or a path
        that is a folder.
    """
    import os
    from pathlib import Path

    from mppf.core.errors import InputError

    path = Path(path)
    if suffixes is not None and path.suffix.lower() not in suffixes:
        raise InputError(f"cannot write {what} {path}: unknown {kind} type {path.suffix or '(no suffix)'!r}",
                         hint=f"give it one of the suffixes {', '.join(suffixes)}")
    folder = path.parent
    if not folder.is_dir():
        raise InputError(f"cannot write {what} {path}: the folder {folder} does not exist",
                         hint="create the folder or give another path")
    if path.is_dir():
        raise InputError(f"cannot write {what} {path}: it is a folder", hint="give a file name")
    if not os.access(folder, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise InputError(f"cannot write {what} {path}: permission denied",
                         hint="give a path in a folder you may write to")
    return path
