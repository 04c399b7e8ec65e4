"""The audit log: every command and every write sent to a PLC, in SQLite, written ahead.

One row per action (claim, upload of a setpoint block, validate, GO, the motion that
follows, STOP, RESET, release, ...), with the time, the PLC URL, the job hash, the job
sequence number and the outcome. The row is **written ahead**: :meth:`AuditLog.intent`
commits it (outcome ``intent``) before the request is sent, :meth:`AuditLog.outcome`
fills in the outcome and its time afterwards. A crash (kill -9, power loss) between the
two leaves the row with outcome ``intent`` and no outcome time: the request may or may not
have reached the PLC. A partial upload leaves the intent rows of its blocks.

The database is in WAL mode with a busy timeout, so several ``mppf`` processes (and
threads) may append at the same time. Default location: ``$MPPF_HOME/audit.sqlite`` when
``MPPF_HOME`` is set, else ``~/.local/share/mppf/audit.sqlite``. A log of schema version 1
(no outcome time) is upgraded in place when opened.

A row that cannot be written (disk full, read-only file, locked past the busy timeout) stops
the request it was for: :meth:`AuditLog.intent` raises :class:`~mppf.core.errors.InputError`
(exit 2) before it is sent, **except for STOP and the release of ownership**, which are sent
whether or not their row can be written (the press stops first). An outcome or a one-shot row that cannot be written
(the request already went out, or nothing is sent) leaves the intent row as it is and is
counted in :attr:`AuditLog.unwritten`, so that a failing log never cuts a motion short
without its STOP.

Master heartbeat writes are not recorded (several a second would drown the log); each
connection (or failed attempt to connect) is.
"""

from __future__ import annotations

import getpass
import os
import socket
import threading
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

from mppf.core.db import Transaction, open_sqlite
from mppf.core.errors import InputError
from mppf.core.paths import data_dir

SCHEMA_VERSION = 2
ALWAYS_SENT = ("stop", "release")
"""Requests sent whether or not their audit row can be written: they only make the press safer."""
INTENT = "intent"
"""The outcome of a row whose request was about to be sent and whose outcome never came."""
_SCHEMA = """
CREATE TABLE IF NOT EXISTS audit (
    id          INTEGER PRIMARY KEY AUTOINCREMENT,
    time_utc    TEXT    NOT NULL,  -- ISO 8601, UTC, microseconds
    time_s      REAL    NOT NULL,  -- Unix time (s)
    host        TEXT    NOT NULL,  -- computer that sent the request
    user        TEXT    NOT NULL,  -- operating-system user
    pid         INTEGER NOT NULL,  -- process id
    plc         TEXT    NOT NULL,  -- PLC URL
    job_sha256  TEXT,              -- SHA-256 of the job file, NULL outside a job
    sequence    INTEGER,           -- job sequence number, NULL when not applicable
    action      TEXT    NOT NULL,  -- connect, claim, upload, validate, go, complete, stop, reset, release, ...
    outcome     TEXT    NOT NULL,  -- intent (no outcome yet), ok, refused, failed, ...
    detail      TEXT    NOT NULL DEFAULT '',
    outcome_time_s REAL            -- Unix time (s) of the outcome; NULL while only the intent is recorded
);
CREATE INDEX IF NOT EXISTS audit_time ON audit (time_s);
"""


def default_audit_path() -> Path:
    """``$MPPF_HOME/audit.sqlite``, else ``~/.local/share/mppf/audit.sqlite``."""
    return data_dir() / "audit.sqlite"


@dataclass(frozen=True)
class AuditEntry:
    """One row of the audit log (see the module docstring for the columns)."""

    id: int
    time_utc: str
    time_s: float
    host: str
    user: str
    pid: int
    plc: str
    job_sha256: str | None
    sequence: int | None
    action: str
    outcome: str
    detail: str
    outcome_time_s: float | None = None


def _user() -> str:
    try:
        return getpass.getuser()
    except (KeyError, OSError):  # no passwd entry, e.g. in a container
        return str(os.getuid()) if hasattr(os, "getuid") else "?"


class AuditLog:
    """An append-only SQLite audit log.

    Parameters
    ----------
    path : path-like, optional
        Database file (created with its folder). Default :func:`default_audit_path`.

    Raises
    ------
    InputError
        The file cannot be created or is not an SQLite database.
    """

    def __init__(self, path=None):
        self.path = Path(path) if path is not None else default_audit_path()
        self._lock = threading.Lock()
        self._host = socket.gethostname()
        self._user = _user()
        _upgrade_v1(self.path)
        self._db = open_sqlite(self.path, "the audit log", _SCHEMA, SCHEMA_VERSION, threads=True,
                               hint="give a writable path with --audit or set MPPF_HOME")
        self.unwritten = 0
        """Outcomes and one-shot rows that could not be written (see the module docstring)."""

    def _write(self, sql: str, params: tuple, what: str):
        """One statement in its own transaction; a failed write as an InputError naming the log."""
        with self._lock, Transaction(self._db, f"the audit log {self.path}",
                                     hint=f"{what}; free disk space or give a writable --audit path (or set "
                                          "MPPF_HOME), then run again"):
            return self._db.execute(sql, params)

    def _write_or_count(self, sql: str, params: tuple) -> None:
        """A write whose failure must not stop what follows: counted in :attr:`unwritten`."""
        try:
            self._write(sql, params, "")
        except InputError:
            self.unwritten += 1

    def _insert(self, plc: str, action: str, outcome: str, outcome_time_s, job_sha256, sequence, detail) -> int:
        now = time.time()
        stamp = datetime.fromtimestamp(now, tz=timezone.utc).isoformat(timespec="microseconds")
        row = (stamp, now, self._host, self._user, os.getpid(), str(plc), job_sha256, sequence, action, outcome,
               detail, now if outcome_time_s else None)
        sql = ("INSERT INTO audit (time_utc, time_s, host, user, pid, plc, job_sha256, sequence, "
               "action, outcome, detail, outcome_time_s) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)")
        if outcome != INTENT:
            self._write_or_count(sql, row)
            return -1
        if action in ALWAYS_SENT:  # STOP and the release go out whether or not their row can be written
            try:
                return int(self._write(sql, row, "").lastrowid)
            except InputError:
                self.unwritten += 1
                return -1
        return int(self._write(sql, row, f"the {action} was not sent to the PLC {plc}").lastrowid)

    def intent(self, plc: str, action: str, *, job_sha256: str | None = None, sequence: int | None = None,
               detail: str = "") -> int:
        """Commit a row for a request about to be sent (outcome ``intent``); return its id (-1: a STOP or
        release whose row could not be written).

        Raises
        ------
        InputError
            The row cannot be written (disk full, read-only): the request must not be sent.
        """
        return self._insert(plc, action, INTENT, False, job_sha256, sequence, detail)

    def outcome(self, row: int, outcome: str, detail: str = "") -> None:
        """Record the outcome of row ``row`` (committed at once); ``detail`` is added to the intent's."""
        if row < 0:  # its intent could not be written (a STOP or a release)
            self.unwritten += 1
            return
        self._write_or_count(
            "UPDATE audit SET outcome = ?, outcome_time_s = ?, "
            "detail = CASE WHEN ? = '' THEN detail WHEN detail = '' THEN ? ELSE detail || '; ' || ? END "
            "WHERE id = ?",
            (outcome, time.time(), detail, detail, detail, int(row)),
        )

    def record(
        self,
        plc: str,
        action: str,
        outcome: str,
        *,
        job_sha256: str | None = None,
        sequence: int | None = None,
        detail: str = "",
    ) -> None:
        """Append one row with its outcome, in one commit (for what is not sent to the PLC: a connection,
        a refusal before writing); a row that cannot be written is counted in :attr:`unwritten`."""
        self._insert(plc, action, outcome, True, job_sha256, sequence, detail)

    def entries(self, limit: int | None = None) -> list[AuditEntry]:
        """Rows in insertion order (the last ``limit`` rows when given)."""
        with self._lock:
            if limit is None:
                cur = self._db.execute("SELECT * FROM audit ORDER BY id")
            else:
                cur = self._db.execute(
                    "SELECT * FROM (SELECT * FROM audit ORDER BY id DESC LIMIT ?) ORDER BY id", (int(limit),)
                )
            return [AuditEntry(*row) for row in cur.fetchall()]

    def close(self) -> None:
        """Close the database connection."""
        with self._lock:
            self._db.close()

    def __enter__(self) -> AuditLog:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _upgrade_v1(path: Path) -> None:
    """Add the outcome time to a log of schema version 1 (its rows keep their outcomes)."""
    import sqlite3

    if not path.is_file():
        return
    try:
        db = sqlite3.connect(path, timeout=10.0, isolation_level=None)
    except sqlite3.Error:
        return  # open_sqlite reports it
    try:
        if db.execute("PRAGMA user_version").fetchone()[0] == 1:
            db.execute("BEGIN IMMEDIATE")
            db.execute("ALTER TABLE audit ADD COLUMN outcome_time_s REAL")
            db.execute(f"PRAGMA user_version={SCHEMA_VERSION}")
            db.execute("COMMIT")
    except sqlite3.Error:
        pass  # not an audit log of ours: open_sqlite reports it
    finally:
        db.close()


class Audited:
    """An audit row written ahead: the intent on entry, the outcome on exit (``with`` block).

    ``session`` is what sends the request (its ``audit``, ``url`` and ``job_sha256`` are used).
    The block sets :attr:`outcome` (default ``ok``) and :attr:`detail` before it ends or raises;
    an exception without an outcome set records ``failed`` (``interrupted`` for Ctrl-C).
    """

    def __init__(self, session, action: str, *, sequence: int | None = None, detail: str = ""):
        self.session, self.action, self.sequence, self.intent_detail = session, action, sequence, detail
        self.outcome, self.detail = "ok", ""

    def __enter__(self) -> Audited:
        s = self.session
        self.row = s.audit.intent(str(s.url), self.action, job_sha256=s.job_sha256, sequence=self.sequence,
                                  detail=self.intent_detail)
        return self

    def __exit__(self, kind, exc, tb) -> bool:
        if kind is not None and self.outcome == "ok":
            self.outcome = "interrupted" if issubclass(kind, KeyboardInterrupt) else "failed"
            self.detail = self.detail or str(exc)
        self.session.audit.outcome(self.row, self.outcome, self.detail)
        return False


class NullAudit:
    """An audit log that records nothing (library use without a log)."""

    path = None

    def intent(self, plc, action, *, job_sha256=None, sequence=None, detail="") -> int:
        return 0

    def outcome(self, row, outcome, detail="") -> None:
        pass

    def record(self, plc, action, outcome, *, job_sha256=None, sequence=None, detail="") -> None:
        pass


NULL_AUDIT = NullAudit()
