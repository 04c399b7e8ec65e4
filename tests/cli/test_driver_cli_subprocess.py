"""The press commands as an operator runs them: ``mppf press/status/stop/reset`` against a
``mppf sim`` running in its own process, Ctrl-C delivered as a real SIGINT."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time

import pytest
from driver_helpers import small_job, small_press

from mppf.cli import main
from mppf.drivers.audit import AuditLog
from mppf.planning.job import load_job, save_job
from mppf.model.press import example_press_path

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")

ROWS, COLS = 4, 6


@pytest.fixture
def env(tmp_path):
    return dict(os.environ, MPPF_HOME=str(tmp_path / "home"))


@pytest.fixture
def press_toml(tmp_path):
    """The example press cut down to ROWS x COLS, as a file for ``mppf sim --press`` (and installed as this
    machine's press in the data folder, for ``mppf press --plc``)."""
    text = example_press_path().read_text()
    text, n_rows = re.subn(r"(?m)^rows = \d+", f"rows = {ROWS}", text)
    text, n_cols = re.subn(r"(?m)^cols = \d+", f"cols = {COLS}", text)
    assert n_rows == n_cols == 1
    path = tmp_path / "home" / "press.toml"
    path.parent.mkdir(exist_ok=True)
    path.write_text(text)
    return path


def start_sim(env, press_toml, *args):
    """``mppf sim`` on a free port in its own process; return (process, URL)."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "mppf", "sim", "--port", "0", "--press", str(press_toml), "--status-every", "100",
         *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
    )
    line = proc.stdout.readline()
    match = re.search(r"tcp://127\.0\.0\.1:\d+\?unit=1", line)
    if not match:
        proc.kill()
        raise AssertionError(f"mppf sim did not start: {line}{proc.communicate(timeout=10)[1]}")
    return proc, match.group(0)


def end_sim(proc):
    proc.send_signal(signal.SIGINT)
    try:
        out, err = proc.communicate(timeout=10)
    finally:
        proc.kill()
    assert proc.returncode == 0, err
    assert "simulated PLC stopped" in out


def status(url, capsys) -> dict:
    assert main(["status", "--plc", url, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def audit_entries(path):
    if not path.exists():
        return []
    with AuditLog(path) as log:
        return log.entries()


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP], ids=["SIGINT", "SIGTERM", "SIGHUP"])
def test_ctrl_c_sigterm_or_sighup_to_mppf_press_stops_the_plc_first(tmp_path, env, press_toml, capsys, signum):
    job_path = save_job(small_job(small_press(ROWS, COLS), n_steps=1), tmp_path / "job.json")
    audit = tmp_path / "audit.sqlite"
    # real time and no watchdog: a move of ~370 mm takes ~19 s, and only a STOP ends it early
    sim, url = start_sim(env, press_toml, "--time-scale", "1", "--watchdog", "0")
    try:
        press = subprocess.Popen(
            [sys.executable, "-m", "mppf", "press", str(job_path), "--plc", url, "--yes", "--audit", str(audit)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
        )
        try:
            deadline = time.monotonic() + 30.0
            while not any(e.action == "go" for e in audit_entries(audit)):
                assert press.poll() is None, press.communicate()[1]
                assert time.monotonic() < deadline, "mppf press did not send GO"
                time.sleep(0.05)
            time.sleep(0.5)  # the punches are moving
            assert status(url, capsys)["status"]["busy"]
            press.send_signal(signum)
            out, err = press.communicate(timeout=20)
        finally:
            press.kill()
        err = " ".join(err.split())
        assert press.returncode == (129 if signum == signal.SIGHUP else 130), err
        assert "STOP was sent to the press; it came to rest" in err and "Traceback" not in err
        assert "motion job 1 (mm of travel): done" not in err  # a cancelled motion is never reported done
        if signum == signal.SIGHUP:
            assert "SIGHUP (the terminal or session was lost): STOP was sent" in err
        else:
            assert "cancelled by the operator; STOP was sent" in err
        entries = [e for e in audit_entries(audit) if e.action != "release"]
        assert [(e.action, e.outcome) for e in entries][-2:] == [("go", "ok"), ("stop", "ok")]
        assert {e.job_sha256 for e in entries} == {load_job(job_path).sha256()}
        assert entries[-1].sequence == entries[-2].sequence == 1
        if signum != signal.SIGINT:  # the log says why the press was stopped
            assert signal.Signals(signum).name in entries[-1].detail
        # the PLC stopped (no watchdog could have done it) short of the targets
        time.sleep(0.3)  # braking from 20 mm/s at 100 mm/s^2 takes 0.2 s
        report = status(url, capsys)
        assert not report["status"]["busy"] and not report["status"]["in_position"]
        assert not report["status"]["fault"] and report["motion"]["sequence"] == 1 and report["state"] == "STOPPED"
    finally:
        end_sim(sim)


def test_status_stop_reset_against_a_sim_process(tmp_path, env, press_toml, capsys):
    audit = tmp_path / "audit.sqlite"
    sim, url = start_sim(env, press_toml, "--word-order", "CDAB", "--fault", "estop")
    try:
        report = status(url, capsys)
        assert (report["rows"], report["cols"], report["word_order"]) == (ROWS, COLS, "CDAB")
        assert report["status"]["estop"] and report["fault_text"].startswith("ESTOP")
        assert main(["stop", "--plc", url, "--audit", str(audit)]) == 0
        assert "STOP sent" in capsys.readouterr().out
        assert main(["reset", "--plc", url, "--audit", str(audit)]) == 4  # the e-stop is still pressed
        assert "refused RESET" in " ".join(capsys.readouterr().err.split())
        assert status(url, capsys)["status"]["fault"]  # latched: nothing cleared it
    finally:
        end_sim(sim)
    assert [(e.action, e.outcome) for e in audit_entries(audit) if e.action != "connect"] == [
        ("stop", "ok"), ("claim", "ok"), ("reset", "refused"), ("release", "ok")]

    sim, url = start_sim(env, press_toml, "--fault", "overpressure")
    try:
        report = status(url, capsys)
        assert report["status"]["fault"] and report["fault_text"].startswith("OVERPRESSURE")
        assert main(["reset", "--plc", url, "--audit", str(audit)]) == 0
        assert "faults reset" in capsys.readouterr().out
        report = status(url, capsys)
        assert report["status"]["ready"] and not report["status"]["fault"] and report["fault_code"] == 0
    finally:
        end_sim(sim)


@pytest.mark.parametrize("quirk", [(), ("--quirk", "borrow-ids")], ids=["alone", "beside-a-master-borrowing-its-id"])
def test_kill_9_of_the_master_during_motion_the_plc_stops_within_its_watchdog(tmp_path, env, press_toml, quirk):
    """No STOP can come from a killed master: the PLC's watchdog ends the motion, also while another
    master beats in the dead owner's name (its beats lack the owner's auth); the audit log keeps
    the intent row of GO, written before the GO was sent, and no outcome of the motion."""
    from mppf.drivers.modbus_session import ModbusSession

    job_path = save_job(small_job(small_press(ROWS, COLS), n_steps=1), tmp_path / "job.json")
    audit = tmp_path / "audit.sqlite"
    sim, url = start_sim(env, press_toml, "--time-scale", "1", "--watchdog", "1.0", "--scan-ms", "10", *quirk)
    try:
        press = subprocess.Popen(
            [sys.executable, "-m", "mppf", "press", str(job_path), "--plc", url, "--yes", "--audit", str(audit)],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env,
        )
        try:
            deadline = time.monotonic() + 30.0
            while not any(e.action == "go" and e.outcome == "ok" for e in audit_entries(audit)):
                assert press.poll() is None, press.communicate()[1]
                assert time.monotonic() < deadline, "mppf press did not send GO"
                time.sleep(0.05)
            time.sleep(0.5)  # the punches are moving
            with ModbusSession(url, heartbeat_s=None) as plc:
                assert plc.status().state == "EXECUTING" and plc.status().lease_ok
                killed_at = time.monotonic()
                press.send_signal(signal.SIGKILL)
                press.communicate(timeout=10)
                while (st := plc.status()).state == "EXECUTING":
                    assert time.monotonic() - killed_at < 5.0, "the PLC kept moving"
                    time.sleep(0.01)
                stopped_after_s = time.monotonic() - killed_at
                report = plc.status_report()
        finally:
            press.kill()
        assert st.state == "FAULT" and report["fault_text"].startswith("WATCHDOG")
        assert stopped_after_s <= 1.0 + 0.1  # the watchdog time, plus a few scans and this poll
        assert not report["status"]["owned"]  # the lease lapsed with the heartbeat
        entries = audit_entries(audit)
        go = [e for e in entries if e.action == "go"]
        assert len(go) == 1 and go[0].time_s < go[0].outcome_time_s  # the intent was committed before GO left
        assert entries[-1].action == "go"  # no outcome of the motion, no STOP, no release: the master died
        assert all(e.outcome != "intent" for e in entries[:-1])
    finally:
        end_sim(sim)
