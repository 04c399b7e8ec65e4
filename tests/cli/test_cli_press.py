"""``mppf press``, ``mppf status``, ``mppf stop``, ``mppf reset`` against the simulated PLC."""

from __future__ import annotations

import io
import json
import time

import numpy as np
import pytest
from driver_helpers import install_press, running_sim, small_job, small_press

from mppf.cli import main
from mppf.drivers.audit import AuditLog
from mppf.core.seal import load_key, seal_document
from mppf.planning.job import save_job
from mppf.model.press import press_to_toml
from mppf.sim.plc.host import start_simulated_plc


@pytest.fixture
def press():
    return small_press()


@pytest.fixture
def job_path(tmp_path, press):
    return save_job(small_job(press, n_steps=2), tmp_path / "job.json")


sim = pytest.fixture(running_sim, name="sim")


# The default audit log kept out of the user's home; this machine's press (installed there) is the small one.
mppf_home = pytest.fixture(install_press, name="mppf_home", autouse=True)


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
        ("claim", "ok"), ("upload", "ok"), ("upload", "ok"), ("validate", "ok"), ("go", "ok"), ("complete", "ok"),
        ("release", "ok")]


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
    # step 2 is out of limits: not even step 1 was uploaded; refused before the PLC was connected, and audited
    assert [a[:2] for a in audit_actions(audit)] == [("limits", "refused")]
    assert (sim.actual_positions_mm()[0] == before[0]).all()


def test_real_plc_without_confirmation_is_refused(job_path, press, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr("sys.stdin", io.StringIO(""))  # not a terminal
    audit = tmp_path / "audit.sqlite"
    real = start_simulated_plc(press, time_scale=50.0)
    try:
        assert main(["press", str(job_path), "--plc", real.url, "--audit", str(audit)]) == 4
        before = real.actual_positions_mm()
    finally:
        real.stop()
    assert "without confirmation" in capsys.readouterr().err
    assert "upload" not in [a[0] for a in audit_actions(audit)]
    assert (before[0] == press.upper.park_mm).all()  # nothing moved


def test_a_simulator_reached_with_plc_is_asked_for_like_any_plc(job_path, sim, tmp_path, monkeypatch, capsys):
    """Nothing a PLC says about itself skips the question: only the in-process dry run moves unasked."""
    monkeypatch.setattr("sys.stdin", io.StringIO(""))  # not a terminal
    audit = tmp_path / "audit.sqlite"
    assert main(["press", str(job_path), "--plc", sim.url, "--audit", str(audit)]) == 4
    assert "without confirmation" in " ".join(capsys.readouterr().err.split())
    assert [a[0] for a in audit_actions(audit)] == ["connect"] and sim.server.master_writes == 0
    assert main(["press", str(job_path), "--audit", str(audit)]) == 0  # the dry run asks nothing


def test_real_plc_with_yes_runs(job_path, sim, tmp_path, capsys):
    # the simulator at --plc moves 50x faster than the press: said with --time-scale, else its COMPLETE is refused
    args = ["press", str(job_path), "--plc", sim.url, "--yes", "--audit", str(tmp_path / "a.sqlite")]
    assert main(args + ["--time-scale", "50"]) == 0
    out = capsys.readouterr().out
    assert "2 step(s) pressed" in out and "dry run" not in out


def test_a_press_stopped_by_someone_else_is_named_before_its_reset(job_path, sim, tmp_path, capsys):
    audit = tmp_path / "a.sqlite"
    assert main(["stop", "--plc", sim.url, "--audit", str(tmp_path / "other.sqlite")]) == 0  # another operator
    assert sim.state() == "STOPPED"
    capsys.readouterr()
    assert main(["press", str(job_path), "--plc", sim.url, "--yes", "--time-scale", "50", "--audit", str(audit)]) == 0
    err = " ".join(capsys.readouterr().err.split())
    assert "is STOPPED by a STOP request of master 0x" in err and "1 STOP request(s)" in err and "yes (--yes)" in err
    assert ("foreign stop", "reset confirmed") in [a[:2] for a in audit_actions(audit)]


def test_without_a_terminal_a_foreign_stop_is_named_in_the_refusal(job_path, sim, tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("sys.stdin", io.StringIO(""))  # no terminal
    assert main(["stop", "--plc", sim.url]) == 0
    capsys.readouterr()
    assert main(["press", str(job_path), "--plc", sim.url, "--audit", str(tmp_path / "a.sqlite")]) == 4
    err = " ".join(capsys.readouterr().err.split())
    assert "stdin is not a terminal" in err and "also STOPPED by a STOP request of master 0x" in err
    assert sim.state() == "STOPPED"  # nothing written, nothing reset


def test_a_complete_sooner_than_the_press_can_move_is_refused(job_path, sim, tmp_path, capsys):
    audit = tmp_path / "a.sqlite"
    assert main(["press", str(job_path), "--plc", sim.url, "--yes", "--audit", str(audit)]) == 4
    err = " ".join(capsys.readouterr().err.split())
    assert "the PLC reported COMPLETE after" in err and "cannot be believed" in err and "at rest" in err
    assert ("complete", "too soon") in [a[:2] for a in audit_actions(audit)]
    assert not sim.wait_idle(2.0)["busy"]


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
    assert report["fault_code"] == 0 and report["validated"]["sequence"] == 0 and report["state"] == "IDLE"
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

    monkeypatch.setattr("mppf.cli._common.RichReporter.update", operator_presses_ctrl_c)
    audit = tmp_path / "audit.sqlite"
    assert main(["press", str(job_path), "--audit", str(audit), "--time-scale", "2"]) == 130
    assert "STOP was sent" in " ".join(capsys.readouterr().err.split())
    assert [a[:2] for a in audit_actions(audit) if a[0] != "release"][-2:] == [("go", "ok"), ("stop", "ok")]


# ------------------------------------------------------------ tampered jobs ------
def _edit(doc: dict, kind: str) -> None:
    """Tamper with a job document the way a hand edit (or a broken tool) would."""
    up, lo = doc["steps"][0]["upper_mm"], doc["steps"][0]["lower_mm"]
    if kind == "bool":
        up[1][2] = True
    elif kind == "string":
        up[1][2] = "12.5"
    elif kind == "nan":
        lo[2][3] = float("nan")
    elif kind == "active":
        doc["steps"][0]["active"][1][1] = "yes"
    elif kind == "limit":
        doc["steps"][1]["upper_mm"][1][2] = 450.0
    elif kind == "gap":
        up[2][2] = lo[2][2] - 50.0  # the upper tip 50 mm below the lower tip
    elif kind == "dimpling":
        up[2][3] += 250.0  # one punch 250 mm above its neighbours
        lo[2][3] += 250.0
    elif kind == "parked":
        up[0][0] = 100.0  # a stroke for the parked punch
    elif kind == "reversal":
        doc["steps"][1]["lower_mm"][3][4] = lo[3][4] - 5.0  # step 2 moves back
        doc["steps"][1]["upper_mm"][3][4] = up[3][4] - 5.0
    elif kind == "thickness":
        doc["thickness_mm"] = 60.0
    elif kind == "parks":
        doc["press"]["upper"]["park_mm"], doc["press"]["lower"]["park_mm"] = -300.0, 300.0
    elif kind == "plc_limits":  # a press block widened: consistent in itself, only the PLC can tell
        doc["press"]["upper"]["max_mm"] = doc["press"]["upper"]["park_mm"] = 500.0


TAMPERED = {
    "bool": "step 1 upper punch (row 2, col 3): stroke true is not a finite number of mm",
    "string": 'step 1 upper punch (row 2, col 3): stroke "12.5" is not a finite number of mm',
    "nan": "step 1 lower punch (row 3, col 4): stroke NaN is not a finite number of mm",
    "active": 'step 1 punch (row 2, col 2): active is "yes", not true or false',
    "limit": "step 2 upper punch (row 2, col 3): stroke 450.00 mm beyond the stroke limits -300..400 mm",
    "gap": "step 1 punch pair (row 3, col 3): tip gap -50.00 mm < thickness 20 mm",
    "dimpling": ("step 1 upper punches (row 3, col 3) and (row 3, col 4): the height difference changes by +2",
                 "mm, dimpling limit 30 mm"),
    "parked": "step 1 upper punch (row 1, col 1) is parked (not active) but has a stroke 100.00 mm; parked punches "
              "stand at park 400.0 mm",
    "reversal": "step 2 lower punch (row 4, col 5) reverses direction: moves -5.00 mm",
    "thickness": "the plate thickness 60 mm is above the largest plate this press takes, [forming] "
                 "max_thickness_mm 50 mm",
    "parks": "[upper] park_mm -300 mm is below [lower] park_mm 300 mm: the parked tips would cross",
    "plc_limits": ("the job was planned for another press than the installed press",
                   "[upper] max_mm is 500.0 in the job, 400.0 in"),
}
RESEALED = {"limit", "gap", "dimpling", "reversal", "thickness", "parks", "plc_limits"}
"""Tampered jobs sealed again (the seal alone would refuse them): the job validator's own refusals."""


@pytest.mark.parametrize("kind", sorted(TAMPERED))
def test_every_tampered_job_exits_2_naming_punch_value_and_limit_and_writes_nothing(
        kind, job_path, tmp_path, sim, capsys):
    doc = json.loads(job_path.read_text())
    _edit(doc, kind)
    if kind in RESEALED:  # sealed again as if by someone with the key: the validator must still refuse it
        doc = seal_document(doc, load_key(), sealed_by="a test")
    path = tmp_path / f"tampered-{kind}.json"
    path.write_text(json.dumps(doc))
    audit = tmp_path / "audit.sqlite"
    assert main(["press", str(path), "--plc", sim.url, "--yes", "--audit", str(audit)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    expected = TAMPERED[kind] if isinstance(TAMPERED[kind], tuple) else (TAMPERED[kind],)
    assert all(part in err for part in expected) and "Traceback" not in err, err
    # nothing reached the PLC: no write request at all, no write in the audit log, nothing moved
    assert sim.server.master_writes == 0
    assert {a[0] for a in audit_actions(audit)} <= {"connect", "limits"}
    assert sim.state() == "IDLE"
    np.testing.assert_array_equal(sim.actual_positions_mm()[0], np.full(sim.plc.press.shape,
                                                                        sim.plc.press.upper.park_mm))


def test_a_job_for_another_press_file_or_another_matrix_exits_2(job_path, tmp_path, press, sim, capsys):
    other = press.to_dict()
    other["forming"]["max_neighbour_diff_mm"] = 25.0
    press_toml = tmp_path / "other.toml"
    press_toml.write_text(
        "\n".join([f'name = "{other["name"]}"'] + [
            f"[{table}]\n" + "\n".join(f"{k} = {v!r}" for k, v in other[table].items())
            for table in ("matrix", "upper", "lower", "forming")]))
    assert main(["press", str(job_path), "--plc", sim.url, "--yes", "--press", str(press_toml)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert f"the job was planned for another press than {press_toml}: [forming] max_neighbour_diff_mm is 30.0 " \
           f"in the job, 25.0 in {press_toml}" in err
    wide = save_job(small_job(small_press(5, 6)), tmp_path / "wide.json")
    assert main(["press", str(wide), "--plc", sim.url, "--yes"]) == 2  # another press than the installed one
    assert "[matrix] rows is 5 in the job, 4 in the installed press" in " ".join(capsys.readouterr().err.split())
    wide_toml = tmp_path / "wide.toml"
    wide_toml.write_text(press_to_toml(small_press(5, 6)))
    assert main(["press", str(wide), "--plc", sim.url, "--yes", "--press", str(wide_toml)]) == 2  # and the PLC's
    assert "drives 4 x 6 punches" in " ".join(capsys.readouterr().err.split())
    assert sim.server.master_writes == 0


@pytest.mark.parametrize("quirk, code, said", [
    ("literal-complete", 4, "the PLC reported COMPLETE after"),
    ("late-status:3", 0, "2 step(s) pressed"),
    ("borrow-ids", 0, "2 step(s) pressed"),
    ("none-after-go", 0, "2 step(s) pressed"),
    ("foreign-stop@2.0", 4, "was stopped by a STOP request of master 0xF0E1D2C3"),
])
def test_mppf_press_against_each_misbehaving_plc_ends_at_rest(job_path, press, tmp_path, capsys, quirk, code, said):
    """The scenarios of docs/simulator.md ("Quirks"), as the operator runs them: exit code, message, press at rest."""
    sim = start_simulated_plc(press, time_scale=20.0, watchdog_s=2.0, quirks=[quirk])
    try:
        result = main(["press", str(job_path), "--plc", sim.url, "--yes", "--time-scale", "20",
                       "--audit", str(tmp_path / "a.sqlite")])
        out, err = capsys.readouterr()
        assert result == code, err
        assert said in " ".join((out + err).split())
        assert "Traceback" not in err
        if code:  # a motion that did not end well is never reported done
            assert not [line for line in err.splitlines() if "motion job" in line and "done in" in line], err
        bits = sim.status_bits()
        assert not bits["busy"] and not sim._call(lambda: sim.plc.hydraulics.moving)  # at rest when mppf exits
        assert sim._call(lambda: sim.plc.owner) == 0  # and the lease given back (after rest)
    finally:
        sim.stop()
