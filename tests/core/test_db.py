"""The one way of opening SQLite and its transactions (mppf.core.db): schema versions, rollback, full and read-only disks."""

from __future__ import annotations

import sqlite3

import pytest

from mppf.core.db import Transaction, open_sqlite
from mppf.core.errors import InputError


def test_open_sqlite_creates_applies_the_schema_and_refuses_another_version(tmp_path):
    path = tmp_path / "sub" / "x.sqlite"
    db = open_sqlite(path, "the test file", "CREATE TABLE IF NOT EXISTS t (a)", 3, hint="h")
    db.execute("INSERT INTO t VALUES (1)")
    assert db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    db.close()
    with pytest.raises(InputError, match="schema version 3, this mppf reads 4"):
        open_sqlite(path, "the test file", "CREATE TABLE IF NOT EXISTS t (a)", 4, hint="h")
    (tmp_path / "bad.sqlite").write_text("not a database at all " * 100)
    with pytest.raises(InputError, match="cannot open the test file"):
        open_sqlite(tmp_path / "bad.sqlite", "the test file", "CREATE TABLE IF NOT EXISTS t (a)", 1, hint="h")
    assert isinstance(sqlite3.connect(path).execute("SELECT a FROM t").fetchone()[0], int)


def test_transaction_commits_rolls_back_and_nests(tmp_path):
    db = open_sqlite(tmp_path / "t.sqlite", "the test db", "CREATE TABLE IF NOT EXISTS t (x);", 1, hint="")
    with Transaction(db, "the test db"):
        db.execute("INSERT INTO t VALUES (1)")
        with Transaction(db, "the test db"):  # joins the outer one
            db.execute("INSERT INTO t VALUES (2)")
    with pytest.raises(ZeroDivisionError), Transaction(db, "the test db"):
        db.execute("INSERT INTO t VALUES (3)")
        raise ZeroDivisionError
    assert [r[0] for r in db.execute("SELECT x FROM t")] == [1, 2]
    db.close()


def test_a_full_database_is_an_input_error_and_nothing_of_the_block_is_kept(tmp_path):
    db = open_sqlite(tmp_path / "full.sqlite", "the test db", "CREATE TABLE IF NOT EXISTS t (x);", 1, hint="")
    db.execute("PRAGMA max_page_count = %d" % db.execute("PRAGMA page_count").fetchone()[0])
    with pytest.raises(InputError, match=r"cannot write the test db: the disk is full") as full:
        with Transaction(db, "the test db", hint="free some space"):
            db.execute("INSERT INTO t VALUES ('small')")
            db.execute("INSERT INTO t VALUES (?)", ("x" * 100_000,))
    assert full.value.hint == "free some space"
    assert db.execute("SELECT COUNT(*) FROM t").fetchone()[0] == 0 and not db.in_transaction
    db.close()


def test_a_read_only_database_is_an_input_error(tmp_path):
    path = tmp_path / "ro.sqlite"
    open_sqlite(path, "the test db", "CREATE TABLE IF NOT EXISTS t (x);", 1, hint="").close()
    db = sqlite3.connect(f"file:{path}?mode=ro", uri=True, isolation_level=None)
    with pytest.raises(InputError, match="read-only"), Transaction(db, "the test db"):
        db.execute("INSERT INTO t VALUES (1)")
    db.close()
