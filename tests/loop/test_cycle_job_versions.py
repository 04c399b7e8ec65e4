"""A cycle's job file is checked against the SHA-256 the history recorded, whichever job format version wrote it:
a version-4 job recorded by an older mppf still resumes; a file replaced since is refused."""

from __future__ import annotations

import hashlib
import json

import pytest
from driver_helpers import small_job, small_press

from mppf.core.errors import ConfigError
from mppf.core.seal import load_key, seal_document
from mppf.loop.records import CycleRecord, load_cycle_job
from mppf.loop.states import CycleState
from mppf.planning.job import save_job


def _record(path, sha256: str) -> CycleRecord:
    return CycleRecord(
        plate_id="P", cycle=1, state=CycleState.PLANNED, created_utc="2026-01-01T00:00:00+00:00",
        updated_utc="2026-01-01T00:00:00+00:00", job_path=str(path), job_sha256=sha256, steps=[],
        step_started=0, steps_done=0, results=[], interrupted=False, scan_path=None, scan_sha256=None, rms_mm=None,
        max_abs_mm=None, within_pct=None, punch_deviation_mm=None, comparison=None, gain=None, correction=None,
        decision=None,
    )


def _write_version_4(path, n_steps: int) -> str:
    """A sealed version-4 job as an older mppf wrote it; the SHA-256 of the file's bytes (what it recorded)."""
    doc = small_job(small_press(), n_steps=n_steps).to_dict()
    doc["version"] = 4
    path.write_text(json.dumps(seal_document(doc, load_key(), sealed_by="mppf loop"), indent=1))
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_a_version_4_cycle_job_recorded_by_an_older_mppf_resumes(tmp_path):
    path = tmp_path / "cycle-01.job.json"
    recorded = _write_version_4(path, 2)
    job = load_cycle_job(_record(path, recorded))
    assert len(job.steps) == 2 and job.sha256() != recorded  # read in this version's layout
    _write_version_4(path, 3)  # replaced since it was recorded (sealed, but not the recorded file)
    with pytest.raises(ConfigError, match="changed since it was recorded"):
        load_cycle_job(_record(path, recorded))


def test_a_cycle_job_this_mppf_wrote_is_its_own_hash(tmp_path):
    job = small_job(small_press())
    path = save_job(job, tmp_path / "cycle-01.job.json")
    assert job.sha256() == hashlib.sha256(path.read_bytes()).hexdigest()
    assert load_cycle_job(_record(path, job.sha256())).sha256() == job.sha256()
    with pytest.raises(ConfigError, match="changed since it was recorded"):
        load_cycle_job(_record(path, "0" * 64))
