"""One loop per plate: a lease in the plate history, held while a process drives the plate.

The lease is a row of the ``leases`` table (plate, owner, host, pid, heartbeat time, a
token). :func:`take_lease` takes it in one ``BEGIN IMMEDIATE`` transaction, so of two
``mppf loop --resume`` started together on one plate exactly one gets it; the other is
refused with a message naming the owner. The holder renews the heartbeat every
:data:`LEASE_BEAT_S` from a thread with its own connection. A lease is stale, and taken
over, when its heartbeat is older than :data:`LEASE_EXPIRY_S` (the holder hung, or died on
another machine) or when its process is gone on this host (``kill -9``, a power cut).
"""

from __future__ import annotations

import contextlib
import getpass
import os
import socket
import sqlite3
import threading
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass

from mppf.core.errors import InputError

LEASE_BEAT_S = 5.0
"""How often the holder renews its heartbeat (s)."""

LEASE_EXPIRY_S = 30.0
"""A lease whose heartbeat is older than this (s) is stale and may be taken over."""

LEASE_SCHEMA = """
CREATE TABLE IF NOT EXISTS leases (
    plate_id      TEXT PRIMARY KEY,
    owner         TEXT NOT NULL,     -- user name
    host          TEXT NOT NULL,
    pid           INTEGER NOT NULL,
    token         TEXT NOT NULL,     -- this holding (a restarted process gets a new one)
    taken_s       REAL NOT NULL,     -- Unix time
    heartbeat_s   REAL NOT NULL      -- Unix time of the last renewal
);
"""


@dataclass(frozen=True)
class Lease:
    """Who holds a plate (a row of ``leases``)."""

    plate_id: str
    owner: str
    host: str
    pid: int
    token: str
    taken_s: float
    heartbeat_s: float

    def describe(self, now_s: float) -> str:
        """``alice on host press-pc, pid 4242, heartbeat 3 s ago``."""
        return f"{self.owner} on host {self.host}, pid {self.pid}, heartbeat {now_s - self.heartbeat_s:.0f} s ago"

    def stale(self, now_s: float, expiry_s: float = LEASE_EXPIRY_S) -> str | None:
        """Why the lease may be taken over (its heartbeat expired, its process died here), or None."""
        if now_s - self.heartbeat_s > expiry_s:
            return f"its heartbeat expired {now_s - self.heartbeat_s:.0f} s ago"
        if self.host == socket.gethostname() and not _alive(self.pid):
            return f"its process {self.pid} has ended"
        return None


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs on this host (a zombie counts as ended)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return True


def current_lease(db: sqlite3.Connection, plate_id: str) -> Lease | None:
    """The lease of ``plate_id``, or None."""
    row = db.execute("SELECT plate_id, owner, host, pid, token, taken_s, heartbeat_s FROM leases "
                     "WHERE plate_id = ?", (plate_id,)).fetchone()
    return None if row is None else Lease(*row)


def take_lease(db: sqlite3.Connection, transaction, plate_id: str, *,
               expiry_s: float = LEASE_EXPIRY_S) -> tuple[Lease, str | None]:
    """Take the lease of ``plate_id`` for this process.

    Parameters
    ----------
    db : sqlite3.Connection
    transaction : callable
        Returns the history's transaction context.
    plate_id : str
    expiry_s : float
        Age of a heartbeat after which a lease is stale (s).

    Returns
    -------
    (Lease, str or None)
        The lease taken, and why an earlier holder's lease was taken over (None: it was free).

    Raises
    ------
    InputError
        Another live process holds it (the message names it).
    """
    now = time.time()
    mine = Lease(plate_id, _user(), socket.gethostname(), os.getpid(), uuid.uuid4().hex, now, now)
    with transaction():
        held = current_lease(db, plate_id)
        why = None if held is None else held.stale(now, expiry_s)
        if held is not None and why is None:
            raise InputError(
                f"plate {plate_id!r} is being run by another mppf loop: {held.describe(now)}",
                hint=f"wait for it to end, or stop that process; a lease whose heartbeat is older than "
                     f"{expiry_s:g} s, or whose process has ended on this host, is taken over",
            )
        db.execute("INSERT OR REPLACE INTO leases VALUES (?, ?, ?, ?, ?, ?, ?)",
                   (mine.plate_id, mine.owner, mine.host, mine.pid, mine.token, mine.taken_s, mine.heartbeat_s))
    return mine, None if held is None else f"{held.describe(now)}: {why}"


def renew_lease(db: sqlite3.Connection, lease: Lease) -> bool:
    """Renew the heartbeat; False when the lease is no longer ours (taken over)."""
    cur = db.execute("UPDATE leases SET heartbeat_s = ? WHERE plate_id = ? AND token = ?",
                     (time.time(), lease.plate_id, lease.token))
    return cur.rowcount == 1


def release_lease(db: sqlite3.Connection, lease: Lease) -> None:
    """Give the lease back (only if still ours)."""
    db.execute("DELETE FROM leases WHERE plate_id = ? AND token = ?", (lease.plate_id, lease.token))


@contextlib.contextmanager
def heartbeat(connect, lease: Lease, every_s: float = LEASE_BEAT_S) -> Iterator[None]:
    """Renew ``lease`` every ``every_s`` from a thread, on its own connection ``connect()``, during the block."""
    stop = threading.Event()

    def beat() -> None:
        db = connect()
        try:
            while not stop.wait(every_s):
                try:
                    if not renew_lease(db, lease):
                        return
                except sqlite3.Error:  # a busy or full disk: try again at the next beat
                    continue
        finally:
            db.close()

    thread = threading.Thread(target=beat, name=f"mppf-lease-{lease.plate_id}", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join(timeout=2.0)


@contextlib.contextmanager
def hold(db: sqlite3.Connection, transaction, connect, plate_id: str) -> Iterator[str | None]:
    """Take the lease (:func:`take_lease`), keep its heartbeat (:func:`heartbeat`), give it back after the block.

    Yields why a stale lease was taken over, or None.
    """
    held, taken_over = take_lease(db, transaction, plate_id)
    try:
        with heartbeat(connect, held):
            yield taken_over
    finally:
        with contextlib.suppress(sqlite3.Error):
            release_lease(db, held)


def _user() -> str:
    try:
        return getpass.getuser()
    except (KeyError, OSError):  # no name for this uid (a container)
        return f"uid {os.getuid()}"
