"""What the panel reads besides the live PLC: the plate history, the audit log, the job files.

Everything here only reads: a history or audit log that does not exist is reported as
missing, never created. :func:`running_plc` finds the PLC a running ``mppf loop`` or
``mppf press`` drives from the audit log (every row names its PLC, computer and process),
so the panel follows a dry run's simulated PLC on its random loopback port too.
"""

from __future__ import annotations

import os
import socket
from dataclasses import dataclass
from pathlib import Path

from mppf.core.errors import InputError, MppfError
from mppf.loop.history import History
from mppf.loop.records import CycleRecord, PlateRecord
from mppf.loop.states import CycleState, PlateStatus
from mppf.model.job import Job
from mppf.planning.job import load_job

AUDIT_ROWS_SEARCHED = 500
"""The newest rows of the audit log searched for a running master."""

REPORT_SUFFIXES = (".html", ".svg", ".png", ".pdf")
"""Files of a plate's work folder listed (and served) as its reports."""


@dataclass(frozen=True)
class PlcTarget:
    """A PLC to watch: its URL and how the panel knows it (for the page)."""

    url: str
    source: str


class HistoryReader:
    """Read-only access to the plate history at ``path`` (opened per call, closed after).

    Every method returns empty results while the file does not exist.
    """

    def __init__(self, path):
        self.path = Path(path)

    @property
    def exists(self) -> bool:
        return self.path.is_file()

    def _open(self) -> History:
        if not self.exists:  # never created by a reader
            raise InputError(f"there is no plate history at {self.path} yet",
                             hint="give the history of the loop with --history")
        return History(self.path)

    def plates(self) -> list[PlateRecord]:
        """All plates, newest change first."""
        if not self.exists:
            return []
        with self._open() as h:
            return sorted(h.plates(), key=lambda p: p.updated_utc, reverse=True)

    def plate(self, plate_id: str) -> tuple[PlateRecord, list[CycleRecord]]:
        """A plate and its cycles (InputError when missing)."""
        with self._open() as h:
            return h.plate(plate_id), h.cycles(plate_id)

    def current(self, plate_id: str | None = None) -> tuple[PlateRecord, list[CycleRecord]] | None:
        """The plate to show: ``plate_id``, else the active plate changed last, else the plate changed last."""
        if plate_id:
            return self.plate(plate_id)
        plates = self.plates()
        if not plates:
            return None
        active = [p for p in plates if p.status == PlateStatus.ACTIVE]
        return self.plate((active or plates)[0].plate_id)

    def revision(self) -> str:
        """Changes whenever a plate is added or changes status, or the current plate's cycles move.

        Read from the records (opening the history writes to its file, so its size or time
        would change at every look).
        """
        if not self.exists:
            return "none"
        with self._open() as h:
            plates = h.plates()
            if not plates:
                return "empty"
            active = [p for p in plates if p.status == PlateStatus.ACTIVE]
            current = max(active or plates, key=lambda p: p.updated_utc)
            events = h.events(current.plate_id)
        return f"{len(plates)}-{max(p.updated_utc for p in plates)}-{current.plate_id}-{events[-1].id if events else 0}"

    def events(self, plate_id: str, last: int = 30) -> list:
        """The plate's last state changes, newest first."""
        with self._open() as h:
            return list(reversed(h.events(plate_id)))[:last]


def next_cycle(cycles: list[CycleRecord]) -> CycleRecord | None:
    """The cycle about to be pressed (or being pressed), else the last one."""
    for c in cycles:
        if c.state in (CycleState.PLANNED, CycleState.PRESSING):
            return c
    return cycles[-1] if cycles else None


def read_job(path) -> tuple[Job | None, str]:
    """The job file at ``path`` and "" or None and why it cannot be shown.

    Its seal is checked (:func:`mppf.planning.job.load_job`) and its placements re-derived from
    the plan (:func:`mppf.planning.job_checks.check_plan`): the panel never shows the operator a
    placement that could not be pressed.
    """
    from mppf.planning.job_checks import check_plan

    try:
        job = load_job(path)
        check_plan(job)
        return job, ""
    except MppfError as exc:
        return None, exc.message


def report_files(plate: PlateRecord) -> list[Path]:
    """The report files in the plate's work folder (by name)."""
    folder = Path(plate.settings.get("work_dir", ""))
    if not plate.settings.get("work_dir") or not folder.is_dir():
        return []
    return sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in REPORT_SUFFIXES)


def _process(pid: int) -> str | None:
    """The command line of a running process on this computer, "" when unknown, None when not running."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return None
    except PermissionError:  # running, someone else's
        return ""
    except OSError:
        return None
    try:
        raw = Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return ""
    return " ".join(part.decode(errors="replace") for part in raw.split(b"\0") if part)


def running_plc(audit_path, own_pid: int | None = None) -> PlcTarget | None:
    """The PLC of the newest audit row written by a process still running on this computer.

    Parameters
    ----------
    audit_path : path-like
        The audit log (not created when missing: None).
    own_pid : int, optional
        This process (its own STOP rows are not a running master); default ``os.getpid()``.

    Returns
    -------
    PlcTarget or None
    """
    from mppf.drivers.audit import AuditLog

    path = Path(audit_path)
    if not path.is_file():
        return None
    own_pid = os.getpid() if own_pid is None else own_pid
    host = socket.gethostname()
    with AuditLog(path) as audit:
        rows = audit.entries(limit=AUDIT_ROWS_SEARCHED)
    seen: set[int] = set()
    for row in reversed(rows):
        if row.host != host or row.pid == own_pid or row.pid in seen:
            continue
        seen.add(row.pid)
        command = _process(row.pid)
        if command is None or (command and "mppf" not in command):
            continue
        return PlcTarget(row.plc, f"from the audit log: {_command_name(command)} (pid {row.pid}) drives it")
    return None


def _command_name(command: str) -> str:
    """"mppf loop" from a process's command line ("a process" when unknown)."""
    words = command.split()
    for k, word in enumerate(words):
        if Path(word).name == "mppf":
            return " ".join(["mppf"] + words[k + 1:k + 2])
    return "a process"


def audit_tail(audit_path, last: int = 12) -> list:
    """The last rows of the audit log, newest first (empty when it does not exist)."""
    from mppf.drivers.audit import AuditLog

    path = Path(audit_path)
    if not path.is_file():
        return []
    with AuditLog(path) as audit:
        return list(reversed(audit.entries(limit=last)))
