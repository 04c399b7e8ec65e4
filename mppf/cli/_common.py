"""Shared pieces of the command line: consoles, JSON output, progress, options.

numpy and rich's progress bars are imported only when used (start-up time: see
``benchmarks/bench_startup.py``). User text (plate ids, press names, file names) is printed
through :func:`esc` or with ``markup=False``, never as rich markup.
"""

from __future__ import annotations

import json
import math
import weakref

import click

from mppf.core.markup import escape_markup as esc  # noqa: F401 - user text in rich markup: esc(text)
from mppf.core.progress import LineReporter

PIPE_WIDTH = 100_000
"""Line width when the output is not a terminal: a log or a pipe gets whole lines, never hard-wrapped."""


def _log_friendly_console(**options):
    """A rich console that wraps lines only on a terminal (rich is imported here, at the first print).

    Written to a file or a pipe (a log, a test's captured stream), rich would wrap every
    line at 80 columns, splitting paths and plate ids; here the width is then
    :data:`PIPE_WIDTH`, so each message stays on one line. The check is made at each
    print, so a console created before its stream was redirected still does the right thing.
    """
    from rich.console import Console, ConsoleDimensions

    class LogFriendlyConsole(Console):
        @property
        def size(self) -> ConsoleDimensions:
            size = super().size
            return size if self.is_terminal else ConsoleDimensions(PIPE_WIDTH, size.height)

    return LogFriendlyConsole(**options)


class _LazyConsole:
    """Stands for a :func:`_log_friendly_console`, made on first use (so that importing a command is fast)."""

    def __init__(self, **options):
        self._options = options
        self._console = None

    def real(self):
        """The rich console itself (for rich objects that need one, e.g. a Progress)."""
        if self._console is None:
            self._console = _log_friendly_console(**self._options)
        return self._console

    def __getattr__(self, name):
        return getattr(self.real(), name)


console = _LazyConsole(highlight=False)
err_console = _LazyConsole(stderr=True, highlight=False)

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
    import numpy as np

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


_REPORTERS: weakref.WeakSet = weakref.WeakSet()


def close_reporters() -> None:
    """End every reporter's heartbeat (:func:`mppf.cli.main` calls it when a command ends)."""
    for reporter in list(_REPORTERS):
        reporter.close()


class RichReporter:
    """A :class:`mppf.core.progress.Reporter` on stderr: rich progress bars on a terminal, else plain lines.

    Not writing to a terminal (a log, a pipe, a service), it is a
    :class:`~mppf.core.progress.LineReporter`: timestamped lines, at least one every 5 s
    while work goes on. Status lines are printed as they are (no rich markup).
    """

    def __init__(self, enabled: bool = True):
        self._enabled = enabled
        self._progress = None
        self._task = None
        self._lines = LineReporter(_print_line) if enabled and not err_console.is_terminal else None
        if self._lines is not None:
            _REPORTERS.add(self._lines)  # its heartbeat thread keeps it alive until closed

    def start(self, task: str, total: float | None = None) -> None:
        self.finish()
        if self._lines is not None:
            self._lines.start(task, total)
        if not self._enabled or self._lines is not None:
            return
        from rich.progress import BarColumn, Progress, TaskProgressColumn, TextColumn, TimeElapsedColumn

        self._progress = Progress(TextColumn("{task.description}"), BarColumn(), TaskProgressColumn(),
                                  TimeElapsedColumn(), console=err_console.real(), transient=False)
        self._progress.start()
        self._task = self._progress.add_task(esc(str(task)), total=total)

    def advance(self, amount: float = 1.0) -> None:
        if self._lines is not None:
            self._lines.advance(amount)
        elif self._progress is not None:
            self._progress.advance(self._task, amount)

    def update(self, completed: float) -> None:
        if self._lines is not None:
            self._lines.update(completed)
        elif self._progress is not None:
            self._progress.update(self._task, completed=completed)

    def finish(self) -> None:
        if self._lines is not None:
            self._lines.finish()
        if self._progress is not None:
            self._progress.stop()
            self._progress = None

    def abandon(self, why: str) -> None:
        """End the task without calling it done (the plain lines say why)."""
        if self._lines is not None:
            self._lines.abandon(why)
        if self._progress is not None:
            self._progress.stop()
            self._progress = None

    def info(self, message: str) -> None:
        if self._lines is not None:
            self._lines.info(message)
        elif self._enabled:
            err_console.print(str(message), markup=False, highlight=False)

    def close(self) -> None:
        """Finish, and stop the heartbeat of the plain-line mode."""
        self.finish()
        if self._lines is not None:
            self._lines.close()


def _print_line(line: str) -> None:
    err_console.print(line, markup=False, highlight=False, soft_wrap=True)


MIN_SIZED_POINTS = 10
"""Fewest points of a plate's file whose size :func:`read_input` judges (fewer: the later steps say "too few")."""


def read_input(path, units: str = "mm", scale: float = 1.0, units_option: str = "--units"):
    """:func:`mppf.geometry.read.read_points` of a plate's file, its warnings printed on stderr.

    A plate smaller than :data:`mppf.geometry.read.PLATE_MIN_MM` across is refused (a file in
    metres read as mm, a CAD plate drawn at the wrong scale): no ship plate is that small, and
    the planner would only fail later with a message about the surface.

    Raises
    ------
    GeometryError
        The plate is smaller than ``PLATE_MIN_MM`` across (file, size and what to do named).
    """
    import numpy as np

    from mppf.core.errors import GeometryError
    from mppf.geometry.read import PLATE_MIN_MM, read_points

    cloud = read_points(path, units=units, scale=scale)
    # too few points, or all at one spot: the fit's and unfolding's own messages say so
    extent = float(np.ptp(cloud.points, axis=0).max()) if cloud.n_points >= MIN_SIZED_POINTS else 0.0
    if 0.0 < extent < PLATE_MIN_MM:
        hint = (f"is the file in metres? then give {units_option} m" if units == "mm" else
                "check the file's unit and --scale")
        raise GeometryError(f"{path}: the plate is only {extent:.3g} mm across ({units_option} {units}"
                            f"{f', --scale {scale:g}' if scale != 1.0 else ''}); a plate is at least "
                            f"{PLATE_MIN_MM:g} mm", hint=hint)
    for warning in cloud.warnings:
        err_console.print(f"[bold yellow]warning:[/] {esc(warning)}", highlight=False, soft_wrap=True)
    return cloud


def check_db_path(path, what: str, option: str):
    """Refuse a database path (audit log, history) that cannot be created, before any work is done.

    Missing folders are fine (they are created); a path that is a folder, or below a file,
    or in a folder that may not be written, is an InputError naming ``option``.
    """
    import os
    from pathlib import Path

    from mppf.core.errors import InputError

    path = Path(path)
    if path.is_dir():
        raise InputError(f"{option} {path}: is a folder, not {what}", hint="give a file name, e.g. audit.sqlite")
    folder = path.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise InputError(f"{option} {path}: cannot create {what}: {folder} is a file, not a folder",
                         hint="give a path in a folder")
    if not os.access(folder, os.W_OK) or (path.exists() and not os.access(path, os.W_OK)):
        raise InputError(f"{option} {path}: cannot write {what}: permission denied",
                         hint="give a path in a folder you may write to")
    return path


DESIGN_MAX_POINTS = 400_000
"""Most points of a design (or its flat) unfolded or planned: beyond, the work takes tens of minutes and
gigabytes (2 million points: more than 10 minutes and 6 GB); a plate needs a few thousand."""


def check_design_size(path, n_points: int) -> None:
    """Refuse a design too large to unfold or plan in reasonable time and memory (:data:`DESIGN_MAX_POINTS`)."""
    if n_points > DESIGN_MAX_POINTS:
        from mppf.core.errors import InputError

        raise InputError(f"{path} has {n_points:,} points; a design may have at most {DESIGN_MAX_POINTS:,} "
                         "(beyond, unfolding and planning run for tens of minutes and need gigabytes of memory)",
                         hint="thin the design in the CAD or scanner software (a 20-50 mm grid is plenty), "
                              "or extract the plate with 'mppf extract --spacing 50'")


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

    if not str(path).strip():
        raise InputError(f"{what}: the output path is empty ({str(path)!r})",
                         hint="give a file name after the option, e.g. -o flat.csv")
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
