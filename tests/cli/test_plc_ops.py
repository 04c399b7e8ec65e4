"""``mppf stop``'s work without click: STOP a real simulated PLC over TCP, audited; no PLC is a link error."""

from __future__ import annotations

import socket

import pytest
from mppf.sim.plc.host import run_simulated_plc

from mppf.cli.plc_ops import open_audit, stop_plc
from mppf.core.errors import LinkError


def test_stop_reaches_the_plc_and_is_recorded_in_the_given_audit_log(tmp_path, capsys):
    audit_path = tmp_path / "audit.sqlite"
    with run_simulated_plc(watchdog_s=None) as sim:
        stop_plc(sim.url, audit_path)
        assert sim.state() == "STOPPED"
    out = capsys.readouterr().out
    assert "STOP sent to" in out and "the PLC took it (state STOPPED)" in out
    with open_audit(audit_path) as audit:
        entries = audit.entries()
    stops = [e for e in entries if e.action == "stop"]
    assert len(stops) == 1, [(e.action, e.outcome) for e in entries]
    assert stops[0].outcome == "ok" and stops[0].plc.startswith(sim.url.split("?")[0])
    assert "mppf stop" in stops[0].detail


def test_stop_without_a_plc_listening_is_a_link_error_naming_the_address(tmp_path):
    with socket.socket() as probe:  # a port nobody listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    url = f"tcp://127.0.0.1:{port}"
    with pytest.raises(LinkError) as caught:
        stop_plc(url, tmp_path / "audit.sqlite")
    assert str(port) in str(caught.value)


def test_the_audit_log_is_opened_where_asked(tmp_path):
    path = tmp_path / "folder" / "audit.sqlite"
    path.parent.mkdir()
    with open_audit(path) as audit:
        assert audit.entries() == []
    assert path.exists()
