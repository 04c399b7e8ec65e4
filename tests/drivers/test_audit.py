"""The SQLite audit log."""

import multiprocessing
import sqlite3

import pytest

from mppf.drivers.audit import AuditLog, default_audit_path
from mppf.core.errors import InputError


def test_default_path_follows_mppf_home(monkeypatch, tmp_path):
    monkeypatch.setenv("MPPF_HOME", str(tmp_path / "home"))
    assert default_audit_path() == tmp_path / "home" / "audit.sqlite"
    monkeypatch.delenv("MPPF_HOME")
    monkeypatch.setenv("HOME", str(tmp_path))
    assert default_audit_path() == tmp_path / ".local" / "share" / "mppf" / "audit.sqlite"


def test_records_are_kept_in_order_with_all_fields(tmp_path):
    path = tmp_path / "sub" / "audit.sqlite"
    with AuditLog(path) as log:
        log.record("tcp://127.0.0.1:5020?unit=1", "upload", "ok", job_sha256="ab" * 32, sequence=7,
                   detail="2048 registers")
        log.record("tcp://127.0.0.1:5020?unit=1", "go", "refused", sequence=7, detail="CRC_MISMATCH")
    with AuditLog(path) as again:
        rows = again.entries()
        last = again.entries(limit=1)
    assert [(r.action, r.outcome, r.sequence) for r in rows] == [("upload", "ok", 7), ("go", "refused", 7)]
    assert rows[0].job_sha256 == "ab" * 32 and rows[1].job_sha256 is None
    assert rows[0].detail == "2048 registers" and rows[0].time_utc.endswith("+00:00")
    assert rows[0].time_s <= rows[1].time_s
    assert [r.id for r in last] == [rows[1].id]
    mode = sqlite3.connect(path).execute("PRAGMA journal_mode").fetchone()[0]
    assert mode == "wal"


def _append_many(path, tag, n):
    log = AuditLog(path)
    for k in range(n):
        log.record("tcp://x:1?unit=1", "stop", "ok", sequence=k, detail=tag)
    log.close()


def test_several_processes_can_append_at_once(tmp_path):
    path = tmp_path / "audit.sqlite"
    AuditLog(path).close()
    ctx = multiprocessing.get_context("spawn")
    procs = [ctx.Process(target=_append_many, args=(path, f"p{i}", 40)) for i in range(3)]
    for p in procs:
        p.start()
    for p in procs:
        p.join(60)
        assert p.exitcode == 0
    rows = AuditLog(path).entries()
    assert len(rows) == 120
    assert {r.detail for r in rows} == {"p0", "p1", "p2"}
    for tag in ("p0", "p1", "p2"):
        assert [r.sequence for r in rows if r.detail == tag] == list(range(40))


def test_unwritable_or_bad_file_is_an_input_error(tmp_path):
    bad = tmp_path / "not-a-db.sqlite"
    bad.write_bytes(b"this is not sqlite" * 100)
    with pytest.raises(InputError, match="cannot open the audit log"):
        AuditLog(bad)


def test_rows_are_written_ahead_and_a_crash_leaves_the_intent(tmp_path):
    path = tmp_path / "audit.sqlite"
    log = AuditLog(path)
    row = log.intent("tcp://plc:502?unit=1", "go", sequence=3, detail="crc 0x12345678")
    # another process (the auditor) sees the intent before the request is even sent
    with AuditLog(path) as reader:
        (entry,) = reader.entries()
    assert (entry.action, entry.outcome, entry.outcome_time_s, entry.detail) == ("go", "intent", None, "crc 0x12345678")
    log.outcome(row, "refused", "TOKEN_MISMATCH")
    log.intent("tcp://plc:502?unit=1", "upload", sequence=4, detail="upper setpoints")  # then the process dies
    log.close()
    with AuditLog(path) as again:
        go, upload = again.entries()
    assert (go.outcome, go.detail) == ("refused", "crc 0x12345678; TOKEN_MISMATCH") and go.outcome_time_s >= go.time_s
    assert (upload.action, upload.outcome, upload.outcome_time_s) == ("upload", "intent", None)


def test_a_version_1_log_is_upgraded_in_place(tmp_path):
    path = tmp_path / "old.sqlite"
    db = sqlite3.connect(path)
    db.executescript("""
        CREATE TABLE audit (id INTEGER PRIMARY KEY AUTOINCREMENT, time_utc TEXT NOT NULL, time_s REAL NOT NULL,
            host TEXT NOT NULL, user TEXT NOT NULL, pid INTEGER NOT NULL, plc TEXT NOT NULL, job_sha256 TEXT,
            sequence INTEGER, action TEXT NOT NULL, outcome TEXT NOT NULL, detail TEXT NOT NULL DEFAULT '');
        INSERT INTO audit (time_utc, time_s, host, user, pid, plc, action, outcome)
            VALUES ('2026-01-01T00:00:00+00:00', 1.0, 'h', 'u', 1, 'tcp://x:1?unit=1', 'go', 'ok');
        PRAGMA user_version = 1;
    """)
    db.close()
    with AuditLog(path) as log:
        log.record("tcp://x:1?unit=1", "stop", "ok")
        rows = log.entries()
    assert [(r.action, r.outcome, r.outcome_time_s is None) for r in rows] == [("go", "ok", True),
                                                                               ("stop", "ok", False)]
