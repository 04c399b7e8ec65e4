"""``mppf reseal``: a deliberate change checked in full against the machine's press, sealed again, audited."""

from __future__ import annotations

import json

import pytest
from driver_helpers import small_job, small_press
from mppf.drivers.audit import AuditLog

from mppf.cli import main
from mppf.model.press import press_to_toml
from mppf.planning.job import load_job, save_job


@pytest.fixture
def setup(tmp_path, monkeypatch):
    """A job of the small press, the small press installed as this machine's, an audit log."""
    monkeypatch.setenv("MPPF_HOME", str(tmp_path / "home"))
    press = small_press()
    (tmp_path / "home").mkdir()
    (tmp_path / "home" / "press.toml").write_text(press_to_toml(press))
    return save_job(small_job(press, n_steps=2), tmp_path / "job.json"), tmp_path / "audit.sqlite"


def _edit(path, edit):
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc, indent=1))


def test_a_deliberate_change_is_resealed_and_audited(setup, capsys):
    job, audit = setup
    def lower_pair(doc):
        for key in ("upper_mm", "lower_mm"):
            doc["steps"][1][key][2][3] -= 0.5

    _edit(job, lower_pair)
    assert main(["press", str(job)]) == 2
    assert "changed: step 2" in " ".join(capsys.readouterr().err.split())
    assert main(["reseal", str(job), "--reason", "row 3 col 4 lowered 0.5 mm after the trial", "--audit",
                 str(audit)]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "resealed" in out and "changed since: step 2" in out
    resealed = load_job(job)
    assert resealed.seal.reason == "row 3 col 4 lowered 0.5 mm after the trial"
    assert resealed.seal.sealed_by.startswith("mppf reseal by ")
    with AuditLog(audit) as log:
        (entry,) = [e for e in log.entries() if e.action == "reseal"]
    assert entry.outcome == "ok" and entry.job_sha256 == resealed.sha256()
    assert "row 3 col 4 lowered" in entry.detail and "changed: step 2" in entry.detail and entry.user


def test_a_change_that_fails_validation_is_not_resealed(setup, capsys):
    job, audit = setup
    before = job.read_text()
    _edit(job, lambda d: d["steps"][1]["upper_mm"][2].__setitem__(3, 900.0))
    edited = job.read_text()
    assert main(["reseal", str(job), "--reason", "try", "--audit", str(audit)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "beyond the stroke limits" in err and "it was not resealed" in err
    assert job.read_text() == edited != before
    with AuditLog(audit) as log:
        assert [e for e in log.entries() if e.action == "reseal"] == []


def test_a_press_block_raised_is_refused_against_the_machines_press(setup, capsys):
    job, audit = setup
    _edit(job, lambda d: d["press"]["forming"].update(max_neighbour_diff_mm=300.0))
    assert main(["reseal", str(job), "--reason", "more dimpling", "--audit", str(audit)]) == 2
    assert "[forming] max_neighbour_diff_mm is 300.0 in the job, 30.0 in the installed press" in \
        " ".join(capsys.readouterr().err.split())


@pytest.mark.parametrize("reason, words", [("", "--reason is empty"), ("   ", "--reason is empty"),
                                           ("a\nb", "with control characters"), ("x" * 600, "at most 500")])
def test_a_reason_is_required(setup, reason, words, capsys):
    job, audit = setup
    assert main(["reseal", str(job), "--reason", reason, "--audit", str(audit)]) == 2
    assert words in capsys.readouterr().err


def test_an_older_unsealed_job_is_resealed_after_the_checks(setup, tmp_path, capsys):
    job, audit = setup
    _edit(job, lambda d: (d.pop("seal"), d.update(version=2)))
    assert main(["press", str(job)]) == 2
    assert "older, unsealed job (version 2)" in capsys.readouterr().err
    assert main(["reseal", str(job), "--reason", "checked by hand", "-o", str(tmp_path / "new.json"),
                 "--audit", str(audit)]) == 0
    assert "was unsealed" in capsys.readouterr().out
    assert load_job(tmp_path / "new.json").seal.reason == "checked by hand"


def test_without_an_installed_press_reseal_needs_press(setup, tmp_path, capsys):
    job, audit = setup
    (tmp_path / "home" / "press.toml").unlink()
    assert main(["reseal", str(job), "--reason", "r" * 480, "--audit", str(audit)]) == 2  # a row that cannot fit
    assert "no press description for this machine" in capsys.readouterr().err


def test_a_reseal_the_audit_log_cannot_record_is_not_made(setup, tmp_path, monkeypatch, capsys):
    from driver_helpers import fill_up_audit

    job, audit = setup
    _edit(job, lambda d: d["steps"][1]["upper_mm"][2].__setitem__(3, d["steps"][1]["upper_mm"][2][3] + 0.5))
    edited = job.read_text()
    fill_up_audit(audit, monkeypatch)
    assert main(["reseal", str(job), "--reason", "r" * 480, "--audit", str(audit)]) == 2  # a row that cannot fit
    assert "was not resealed" in " ".join(capsys.readouterr().err.split())
    assert job.read_text() == edited and not list(tmp_path.glob("*.reseal*"))
