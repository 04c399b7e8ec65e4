"""Opening mppf's SQLite files (the audit log, the plate history) the one way."""

from __future__ import annotations

import sqlite3
from pathlib import Path

from mppf.core.errors import InputError

BUSY_TIMEOUT_S = 10.0
"""How long a writer waits for another process's transaction before giving up."""


def open_sqlite(path, what: str, schema: str, version: int, *, hint: str, threads: bool = False) -> sqlite3.Connection:
    """Open (and create) an mppf SQLite database: autocommit, write-ahead log, schema applied.

    Parameters
    ----------
    path : path-like
        The database file; its folder is created.
    what : str
        What the file is, for messages ("the audit log").
    schema : str
        SQL script creating the tables (``CREATE TABLE IF NOT EXISTS ...``).
    version : int
        Schema version this mppf writes (``PRAGMA user_version``); a file with another
        non-zero version is refused.
    hint : str
        What to do when the file cannot be opened.
    threads : bool
        Allow the connection to be used from other threads (calls must still be serialised).

    Returns
    -------
    sqlite3.Connection
        Autocommit (``isolation_level=None``); transactions are opened explicitly.

    Raises
    ------
    InputError
        The folder cannot be created, the file is not an SQLite database, or its schema
        version is another one.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        db = sqlite3.connect(path, timeout=BUSY_TIMEOUT_S, check_same_thread=not threads, isolation_level=None)
        db.execute("PRAGMA journal_mode=WAL")
        db.execute("PRAGMA synchronous=FULL")
        db.executescript(schema)
        found = db.execute("PRAGMA user_version").fetchone()[0]
        if found not in (0, version):
            db.close()
            raise InputError(f"{what} {path} has schema version {found}, this mppf reads {version}",
                             hint=f"use the mppf that wrote it, or another file ({hint})")
        db.execute(f"PRAGMA user_version={version}")
    except (OSError, sqlite3.Error) as exc:
        raise InputError(f"cannot open {what} {path}: {exc}", hint=hint) from None
    return db


class Transaction:
    """``BEGIN IMMEDIATE ... COMMIT`` on an autocommit connection (ROLLBACK on error); nests.

    Inner blocks join the outer transaction. A failed write (disk full, read-only file, a
    database locked past :data:`BUSY_TIMEOUT_S`) is rolled back, so the file holds what it
    held before the block, and reported as an :class:`~mppf.core.errors.InputError` (exit 2)
    naming the file, instead of an internal error.

    Parameters
    ----------
    db : sqlite3.Connection
        Opened by :func:`open_sqlite`.
    what : str
        The file, for messages ("the plate history /data/history.sqlite").
    hint : str
        What to do when a write fails.
    """

    def __init__(self, db: sqlite3.Connection, what: str = "the database", hint: str = ""):
        self._db = db
        self._what = what
        self._hint = hint
        self._outer = False

    def __enter__(self):
        self._outer = not self._db.in_transaction
        if self._outer:
            try:
                self._db.execute("BEGIN IMMEDIATE")
            except sqlite3.OperationalError as exc:
                raise self._error(exc) from None
        return self

    def __exit__(self, exc_type, exc, tb):
        if not self._outer:
            return False
        failed_commit = None
        if exc_type is None:
            try:
                self._db.execute("COMMIT")
                return False
            except sqlite3.Error as error:
                exc_type, exc, failed_commit = type(error), error, error
        if self._db.in_transaction:
            try:
                self._db.execute("ROLLBACK")
            except sqlite3.Error:
                pass
        if issubclass(exc_type, sqlite3.OperationalError):
            raise self._error(exc) from None
        if failed_commit is not None:
            raise failed_commit
        return False

    def _error(self, exc: Exception) -> InputError:
        text = str(exc)
        cause = ("the disk is full" if "full" in text else "the file is read-only" if "readonly" in text
                 else "another program holds it locked" if "locked" in text else text)
        return InputError(f"cannot write {self._what}: {cause} ({text}); nothing of this step was recorded",
                          hint=self._hint or "free disk space or make the file writable, then run again")
