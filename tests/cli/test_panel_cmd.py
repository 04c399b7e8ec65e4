"""``mppf panel``: where it may listen, and what it is given."""

from __future__ import annotations

import pytest

from mppf.cli import main
from mppf.cli import panel_cmd
from mppf.panel.config import check_bind, is_loopback

TOKEN = "a-long-enough-token-0123"


@pytest.mark.parametrize("host", ["127.0.0.1", "127.3.4.5", "localhost", "::1", "[::1]"])
def test_loopback_addresses(host):
    assert is_loopback(host)
    check_bind(host, None)


@pytest.mark.parametrize("host", ["0.0.0.0", "192.168.10.20", "::", "panel.shop"])
def test_other_addresses_need_a_token(host, capsys):
    assert not is_loopback(host)
    assert main(["panel", "--host", host]) == 2
    err = capsys.readouterr().err
    assert "not a loopback address and no --token" in err and "what to do" in err


def test_a_short_token_is_refused_without_showing_it(capsys):
    assert main(["panel", "--host", "0.0.0.0", "--token", "short-secret"]) == 2
    err = capsys.readouterr().err
    assert "too short: 12 characters" in err and "short-secret" not in err


def test_with_a_token_any_address_is_served(monkeypatch, tmp_path):
    served = []
    monkeypatch.setattr(panel_cmd, "serve", served.append)
    monkeypatch.setattr(panel_cmd, "_check_port_free", lambda host, port: None)
    monkeypatch.setenv("MPPF_PANEL_TOKEN", TOKEN)
    assert main(["panel", "--host", "0.0.0.0", "--history", str(tmp_path / "h.sqlite")]) == 0
    (cfg,) = served
    assert cfg.token == TOKEN and cfg.host == "0.0.0.0" and cfg.audit_path == tmp_path / "audit.sqlite"
    assert TOKEN not in repr(cfg)


def test_bad_inputs_exit_2(tmp_path, capsys):
    assert main(["panel", "--plc", "udp://nowhere"]) == 2
    assert main(["panel", "--job", str(tmp_path / "missing.json")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_a_port_in_use_is_refused(capsys):
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        assert main(["panel", "--port", str(port)]) == 2
    assert f"cannot serve the panel on 127.0.0.1:{port}" in capsys.readouterr().err


def test_the_command_refuses_a_network_address_without_a_token():
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-m", "mppf", "panel", "--host", "0.0.0.0", "--port", "8450"],
                          capture_output=True, text=True, timeout=60, stdin=subprocess.DEVNULL)
    assert done.returncode == 2
    assert "refusing to serve the panel on 0.0.0.0" in done.stderr and "Traceback" not in done.stderr
