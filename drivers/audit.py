"""The audit log: every command and every write sent to a PLC, in SQLite.

One row per action (upload, verify, sequence/CRC write, GO, STOP, RESET, ...), with the
time, the PLC URL, the job hash, the job sequence number and the outcome. The database
is in WAL mode with a busy timeout, so several ``mppf`` processes (and threads) may
append at the same time. Default location: ``$MPPF_HOME/audit.sqlite`` when
``MPPF_HOME`` is set, else ``~/.local/share/mppf/audit.sqlite``.

Master heartbeat writes are not recorded (four a second would drown the log); each
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

from mppf.core.errors import InputError
from mppf.core.db import open_sqlite
from mppf.core.paths import data_dir

SCHEMA_VERSION = 1
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
    action      TEXT    NOT NULL,  -- connect, upload, verify, arm, go, stop, reset, ...
    outcome     TEXT    NOT NULL,  -- ok, refused, failed, ...
    detail      TEXT    NOT NULL DEFAULT ''
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
        self._db = open_sqlite(self.path, "the audit log", _SCHEMA, SCHEMA_VERSION, threads=True,
                               hint="give a writable path with --audit or set MPPF_HOME")

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
        """Append one row (committed at once)."""
        now = time.time()
        stamp = datetime.fromtimestamp(now, tz=timezone.utc).isoformat(timespec="microseconds")
        row = (stamp, now, self._host, self._user, os.getpid(), str(plc), job_sha256, sequence,
               action, outcome, detail)
        with self._lock:
            self._db.execute(
                "INSERT INTO audit (time_utc, time_s, host, user, pid, plc, job_sha256, sequence, "
                "action, outcome, detail) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                row,
            )

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


class NullAudit:
    """An audit log that records nothing (library use without a log)."""

    path = None

    def record(self, plc, action, outcome, *, job_sha256=None, sequence=None, detail="") -> None:
        pass


NULL_AUDIT = NullAudit()
