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
