"""An audit log that cannot be written: nothing is sent, except STOP, which always goes out."""

from __future__ import annotations

import pytest
from driver_helpers import fill_up_audit as fill_up

from mppf.core.errors import InputError
from mppf.drivers.audit import AuditLog


def test_an_intent_that_cannot_be_written_refuses_the_request(tmp_path, monkeypatch):
    path = tmp_path / "audit.sqlite"
    fill_up(path, monkeypatch)
    with AuditLog(path) as log:
        with pytest.raises(InputError, match="the disk is full") as error:
            log.intent("tcp://plc:502", "upload", job_sha256="a" * 64, sequence=7, detail="y" * 2000)
        assert "the upload was not sent to the PLC tcp://plc:502" in error.value.hint
        # a one-shot row and an outcome never raise: they are counted
        log.record("tcp://plc:502", "connect", "ok", detail="z" * 2000)
        assert log.unwritten == 1


def test_stop_goes_out_whatever_the_log(tmp_path, monkeypatch):
    path = tmp_path / "audit.sqlite"
    fill_up(path, monkeypatch)
    with AuditLog(path) as log:
        row = log.intent("tcp://plc:502", "stop", detail="operator " + "s" * 2000)
        assert row == -1
        log.outcome(row, "ok")
        assert log.unwritten == 2
    monkeypatch.undo()
    with AuditLog(path) as log:  # what was recorded before is all there
        assert [e.action for e in log.entries()] == ["connect"]
