"""``mppf press`` with an audit log that cannot be written: exit 2, nothing sent to the PLC."""

from __future__ import annotations

import pytest
from driver_helpers import fill_up_audit as fill_up
from driver_helpers import small_job, small_press

from mppf.cli import main
from mppf.drivers.audit import AuditLog
from mppf.planning.job import save_job
from mppf.model.press import press_to_toml
from mppf.sim.plc.host import start_simulated_plc


@pytest.fixture(autouse=True)
def mppf_home(tmp_path, monkeypatch):
    """The data folder, with this machine's press (the small one) installed."""
    monkeypatch.setenv("MPPF_HOME", str(tmp_path / "home"))
    (tmp_path / "home").mkdir()
    (tmp_path / "home" / "press.toml").write_text(press_to_toml(small_press()))


def test_a_full_audit_log_exits_2_and_the_press_gets_nothing(tmp_path, monkeypatch, capsys):
    press = small_press()
    job_path = save_job(small_job(press, n_steps=2), tmp_path / "job.json")
    audit = tmp_path / "audit.sqlite"
    fill_up(audit, monkeypatch)
    sim = start_simulated_plc(press, time_scale=50.0, watchdog_s=2.0)
    try:
        before = sim.actual_positions_mm()
        code = main(["press", str(job_path), "--plc", sim.url, "--yes", "--audit", str(audit)])
        err = " ".join(capsys.readouterr().err.split())
        assert code == 2, err
        assert "cannot write the audit log" in err and "the disk is full" in err and "Traceback" not in err
        assert "not sent to the PLC" in err
        after = sim.actual_positions_mm()
        assert all((a == b).all() for a, b in zip(after, before))
    finally:
        sim.stop()
    monkeypatch.undo()
    with AuditLog(audit) as log:  # the rows that still fitted: nothing was uploaded, validated or started
        actions = [e.action for e in log.entries()]
    assert actions[0] == "connect" and set(actions) <= {"connect", "claim", "release"}, actions
