"""``mppf press``, ``mppf status``, ``mppf stop``, ``mppf reset`` against the simulated PLC."""

from __future__ import annotations

import io
import json
import time

import pytest
from driver_helpers import small_job, small_press

from mppf.cli import main
from mppf.drivers.audit import AuditLog
from mppf.planning.job import save_job
from mppf.sim.plc.host import start_simulated_plc


@pytest.fixture
def press():
    return small_press()


@pytest.fixture
def job_path(tmp_path, press):
    return save_job(small_job(press, n_steps=2), tmp_path / "job.json")


@pytest.fixture
def sim(press):
    handle = start_simulated_plc(press, time_scale=50.0)
    yield handle
    handle.stop()


@pytest.fixture(autouse=True)
def mppf_home(tmp_path, monkeypatch):
    """Keep the default audit log out of the user's home."""
    monkeypatch.setenv("MPPF_HOME", str(tmp_path / "home"))
    return tmp_path / "home"


def audit_actions(path) -> list[tuple[str, str, int | None]]:
    with AuditLog(path) as log:
        return [(e.action, e.outcome, e.sequence) for e in log.entries()]


def test_dry_run_presses_every_step_on_the_simulator(job_path, tmp_path, capsys):
    audit = tmp_path / "audit.sqlite"
    code = main(["press", str(job_path), "--audit", str(audit), "--time-scale", "50"])
    out, err = capsys.readouterr()
    assert code == 0, err
    assert "DRY RUN" in err and "dry run: 2 step(s) pressed" in out
    assert "step 1: job sequence 1" in out and "step 2: job sequence 2" in out
    gos = [a for a in audit_actions(audit) if a[0] == "go"]
    assert gos == [("go", "ok", 1), ("go", "ok", 2)]


def test_dry_run_of_one_step_uses_the_default_audit_log(job_path, mppf_home, capsys):
    assert main(["press", str(job_path), "--step", "2", "--time-scale", "50"]) == 0
    assert "dry run: 1 step(s) pressed" in capsys.readouterr().out
    assert [a[:2] for a in audit_actions(mppf_home / "audit.sqlite") if a[0] != "connect"] == [
        ("upload", "ok"), ("validate", "ok"), ("go", "ok"), ("complete", "ok")]


def test_bad_input_exits_2(job_path, tmp_path, press, capsys):
    assert main(["press", str(tmp_path / "missing.json")]) == 2
    (tmp_path / "bad.json").write_text("{not json")
    assert main(["press", str(tmp_path / "bad.json")]) == 2
    assert main(["press", str(job_path), "--step", "3"]) == 2
    assert "steps 1..2" in capsys.readouterr().err
    assert main(["press", str(job_path), "--plc", "http://plc:502"]) == 2
    assert "unknown scheme" in capsys.readouterr().err
    assert main(["status"]) == 2
    for bad in ("nan", "inf"):
        assert main(["press", str(job_path), "--timeout", bad]) == 2
        err = capsys.readouterr().err
        assert f"--timeout must be a finite number of seconds, got {bad}" in err and "DRY RUN" not in err


def test_strokes_beyond_limits_exit_2_before_anything_moves(tmp_path, press, sim, capsys):
    path = save_job(small_job(press, n_steps=2, beyond_limit=True), tmp_path / "far.json")
    audit = tmp_path / "audit.sqlite"
    before = sim.actual_positions_mm()
    code = main(["press", str(path), "--plc", sim.url, "--yes", "--audit", str(audit)])
    assert code == 2
    assert "beyond the stroke limits" in capsys.readouterr().err
    # step 2 is out of limits: not even step 1 was uploaded
    assert [a[0] for a in audit_actions(audit)] == ["connect", "limits"]
    assert (sim.actual_positions_mm()[0] == before[0]).all()


def test_real_plc_without_confirmation_is_refused(job_path, press, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr("sys.stdin", io.StringIO(""))  # not a terminal
    audit = tmp_path / "audit.sqlite"
    real = start_simulated_plc(press, time_scale=50.0, announce_simulated=False)  # poses as a real press
    try:
        assert main(["press", str(job_path), "--plc", real.url, "--audit", str(audit)]) == 4
        before = real.actual_positions_mm()
    finally:
        real.stop()
    assert "without confirmation" in capsys.readouterr().err
    assert "upload" not in [a[0] for a in audit_actions(audit)]
    assert (before[0] == press.upper.park_mm).all()  # nothing moved


def test_the_simulated_plc_needs_no_confirmation(job_path, sim, tmp_path, monkeypatch, capsys):
    """The simulator sets status bit `simulated`: pressing on it asks nothing, even without a terminal."""
    monkeypatch.setattr("sys.stdin", io.StringIO(""))  # not a terminal
    audit = tmp_path / "audit.sqlite"
    assert main(["press", str(job_path), "--plc", sim.url, "--audit", str(audit)]) == 0
    assert "no confirmation needed" in " ".join(capsys.readouterr().err.split())
    assert "go" in [a[0] for a in audit_actions(audit)]


def test_real_plc_with_yes_runs(job_path, sim, tmp_path, capsys):
    assert main(["press", str(job_path), "--plc", sim.url, "--yes", "--audit", str(tmp_path / "a.sqlite")]) == 0
    out = capsys.readouterr().out
    assert "2 step(s) pressed" in out and "dry run" not in out


def test_estop_during_motion_exits_4_and_the_press_is_stopped(job_path, sim, tmp_path, capsys):
    sim.inject("estop", after_s=1.0)
    audit = tmp_path / "audit.sqlite"
    assert main(["press", str(job_path), "--plc", sim.url, "--yes", "--audit", str(audit)]) == 4
    err = " ".join(capsys.readouterr().err.split())  # the console wraps long lines
    assert "ESTOP" in err and "STOP was sent" in err
    assert ("stop", "ok") in [a[:2] for a in audit_actions(audit)]
    assert not sim.wait_idle(2.0)["busy"]
    # status shows the latched fault; reset is refused while the e-stop is pressed
    assert main(["status", "--plc", sim.url, "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["status"]["estop"] and report["fault_text"].startswith("ESTOP")
    assert main(["reset", "--plc", sim.url, "--audit", str(audit)]) == 4
    sim.release_estop()
    assert main(["reset", "--plc", sim.url, "--audit", str(audit)]) == 0
    assert "faults reset" in capsys.readouterr().out
    assert [a[:2] for a in audit_actions(audit) if a[0] == "reset"] == [("reset", "refused"), ("reset", "ok")]


def test_status_json_and_text(sim, press, capsys):
    time.sleep(0.1)  # a few PLC scans: the PLC heartbeat has counted
    assert main(["status", "--plc", sim.url, "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert (report["rows"], report["cols"], report["word_order"]) == (press.rows, press.cols, "ABCD")
    assert report["status"]["ready"] and not report["status"]["busy"]
    assert report["fault_code"] == 0 and report["acknowledged_sequence"] == 0
    assert report["plc_heartbeat"] > 0 and report["limits_mm"]["lower"] == [press.lower.min_mm, press.lower.max_mm]
    assert main(["status", "--plc", sim.url]) == 0
    out = capsys.readouterr().out
    assert "4 x 6 punches" in out and "ready" in out


def test_stop_command_is_audited(sim, tmp_path, capsys):
    audit = tmp_path / "audit.sqlite"
    assert main(["stop", "--plc", sim.url, "--audit", str(audit)]) == 0
    assert "STOP sent" in capsys.readouterr().out
    assert [a[:2] for a in audit_actions(audit)] == [("connect", "ok"), ("stop", "ok")]


def test_unreachable_plc_exits_3(job_path, capsys):
    assert main(["status", "--plc", "tcp://127.0.0.1:1?timeout=0.2"]) == 3
    assert main(["press", str(job_path), "--plc", "tcp://127.0.0.1:1?timeout=0.2", "--yes"]) == 3
    assert "cannot connect" in capsys.readouterr().err


def test_ctrl_c_during_motion_exits_130_after_stop(job_path, tmp_path, monkeypatch, capsys):
    def operator_presses_ctrl_c(self, completed):
        raise KeyboardInterrupt

    monkeypatch.setattr("mppf.cli.press_cmd.RichReporter.update", operator_presses_ctrl_c)
    audit = tmp_path / "audit.sqlite"
    assert main(["press", str(job_path), "--audit", str(audit), "--time-scale", "2"]) == 130
    assert "STOP was sent" in " ".join(capsys.readouterr().err.split())
    assert [a[:2] for a in audit_actions(audit)][-2:] == [("go", "ok"), ("stop", "ok")]
