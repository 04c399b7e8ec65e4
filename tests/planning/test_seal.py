"""The job seal: made at planning with the installation's key, checked by the one job loader, named when broken."""

from __future__ import annotations

import json
import os
import stat

import numpy as np
import pytest
from driver_helpers import small_job, small_press

from mppf.core.errors import ConfigError
from mppf.core.seal import (
    canonical,
    changed_parts,
    key_id,
    load_key,
    seal_document,
    verify_document,
)
from mppf.planning.job import load_job, save_job


@pytest.fixture
def job_path(tmp_path):
    return save_job(small_job(small_press(), n_steps=3), tmp_path / "job.json")


def _rewrite(path, edit):
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc, indent=1))
    return path


def test_the_key_is_made_once_with_mode_0600_and_kept(tmp_path, monkeypatch):
    key_file = tmp_path / "home" / "seal.key"
    monkeypatch.setenv("MPPF_SEAL_KEY", str(key_file))
    key = load_key()
    assert len(key) == 32 and stat.S_IMODE(os.stat(key_file).st_mode) == 0o600
    assert load_key() == key  # never replaced
    assert key.hex() not in save_job(small_job(small_press()), tmp_path / "j.json").read_text()  # never in the job
    monkeypatch.delenv("MPPF_SEAL_KEY")
    monkeypatch.setenv("MPPF_HOME", str(tmp_path / "other"))
    assert load_key() != key and (tmp_path / "other" / "seal.key").exists()  # per installation (data folder)


def test_a_broken_key_file_is_a_clear_error(tmp_path):
    bad = tmp_path / "seal.key"
    bad.write_text("not hex\n")
    with pytest.raises(ConfigError, match=r"seal key .*seal.key cannot be read as a key"):
        load_key(bad)
    bad.write_text("ab" * 8)
    with pytest.raises(ConfigError, match="holds 8 bytes, not 32"):
        load_key(bad)


def test_a_saved_job_is_sealed_and_loads_and_its_hash_is_the_files(job_path):
    import hashlib

    doc = json.loads(job_path.read_text())
    assert doc["version"] == 5 and doc["seal"]["algorithm"] == "HMAC-SHA256"
    assert doc["seal"]["key_id"] == key_id(load_key())
    job = load_job(job_path)
    assert job.sha256() == hashlib.sha256(job_path.read_bytes()).hexdigest()
    # numbers written otherwise by a JSON tool (20.0 as 20, other spacing) are the same content
    _rewrite(job_path, lambda d: d.update(thickness_mm=int(d["thickness_mm"])))
    load_job(job_path)


@pytest.mark.parametrize("edit, named", [
    (lambda d: d["steps"][1]["upper_mm"][2].__setitem__(3, d["steps"][1]["upper_mm"][2][3] + 2.0), "step 2"),
    (lambda d: d.update(thickness_mm=19.0), "thickness"),
    (lambda d: d["press"]["forming"].update(max_neighbour_diff_mm=300.0), "press"),
    (lambda d: d["steps"].pop(), "step 3 (removed)"),
    (lambda d: d["steps"].insert(0, d["steps"][0]), "step 4 (added)"),
    (lambda d: d["validation"].update(passed=False) if "validation" in d else d.update(validation={}), "validation"),
    (lambda d: d.update(plate={"material": {"youngs_modulus_mpa": 2.1e5, "poisson": 0.3, "yield_stress_mpa": 1.0}}),
     "material"),
    (lambda d: d.update(inputs={"design": {"sha256": "0" * 64}}), "inputs"),
    (lambda d: d["seal"]["parts"].update(press="0" * 64), "the seal block itself"),
])
def test_every_change_is_refused_naming_the_part(job_path, edit, named):
    _rewrite(job_path, edit)
    with pytest.raises(ConfigError) as info:
        load_job(job_path)
    assert "the job was changed after it was sealed" in info.value.message and named in info.value.message
    assert "mppf reseal" in info.value.hint
    with pytest.raises(ConfigError):  # read-only use too: a broken seal is never read
        load_job(job_path, require_seal=False)


def test_a_removed_seal_another_key_and_an_old_job(job_path, tmp_path):
    doc = json.loads(job_path.read_text())
    del doc["seal"]
    (tmp_path / "bare.json").write_text(json.dumps(doc))
    with pytest.raises(ConfigError, match="the job has no seal"):
        load_job(tmp_path / "bare.json", require_seal=False)  # a version-5 job without its seal
    other = seal_document(doc, bytes(32), sealed_by="elsewhere")
    (tmp_path / "other.json").write_text(json.dumps(other))
    with pytest.raises(ConfigError, match="sealed by another installation"):
        load_job(tmp_path / "other.json")
    doc["version"] = 2
    (tmp_path / "old.json").write_text(json.dumps(doc))
    with pytest.raises(ConfigError, match=r"older, unsealed job \(version 2\)") as info:
        load_job(tmp_path / "old.json")
    assert "mppf reseal" in info.value.hint
    assert load_job(tmp_path / "old.json", require_seal=False).thickness_mm == 20.0  # compare, history: read


def test_changed_parts_names_sections_and_the_seal_covers_every_key():
    doc = {"format": "mppf-job", "version": 4, "steps": [{"a": 1}],
           "sections": [{"plate_centre_mm": [0, 0], "steps": [{"a": 1}]}, {"plate_centre_mm": [1, 0], "steps": []}],
           "anything": {"x": 1}}
    key = bytes(range(32))
    sealed = seal_document(doc, key, sealed_by="test")
    verify_document(sealed, "j", key)
    moved = json.loads(json.dumps(sealed))
    moved["sections"][1]["plate_centre_mm"][0] = 1001
    moved["sections"][0]["steps"].append({"a": 1})
    moved["anything"]["x"] = 2
    assert set(changed_parts(moved, key)) == {"section 2 placement", "section 1 step 2 (added)",
                                              "section 1 number of steps", "planner's reports"}
    short = json.loads(json.dumps(sealed))
    short["sections"].pop()
    with pytest.raises(ConfigError, match="number of sections"):
        verify_document(short, "j", key)


def test_canonical_form_refuses_non_finite_numbers():
    assert canonical({"b": 1, "a": [2.0, True, None]}) == b'{"a":[2.0,true,null],"b":1.0}'
    with pytest.raises(ValueError):
        canonical([np.nan])
