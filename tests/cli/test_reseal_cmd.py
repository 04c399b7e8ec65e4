"""``mppf reseal``: what it says of the old seal (unsealed, this installation's with what changed, another's)."""

from __future__ import annotations

import json

import pytest
from driver_helpers import small_job, small_press

from mppf.cli.reseal_cmd import _previous_seal
from mppf.core.seal import SEAL_KEY, load_key, seal_document
from mppf.planning.job import save_job


@pytest.fixture
def doc(tmp_path, monkeypatch):
    """A job document sealed with this installation's key (a key of its own in MPPF_HOME)."""
    monkeypatch.setenv("MPPF_HOME", str(tmp_path / "home"))
    path = save_job(small_job(small_press(), n_steps=2), tmp_path / "job.json")
    return json.loads(path.read_text())


def test_an_unsealed_job_says_so_and_names_no_change(doc):
    unsealed = {k: v for k, v in doc.items() if k != SEAL_KEY}
    assert _previous_seal(unsealed) == ("unsealed", [])


def test_a_job_of_this_installation_names_what_changed_since_its_seal(doc):
    how, changed = _previous_seal(doc)
    assert how.startswith("sealed by ") and changed == []
    doc["steps"][1]["upper_mm"][2][3] -= 0.5  # an active punch of step 2
    assert _previous_seal(doc) == (how, ["step 2"])


def test_a_job_sealed_by_another_installation_names_its_key_and_cannot_tell_what_changed(doc):
    other = seal_document({k: v for k, v in doc.items() if k != SEAL_KEY}, b"k" * 32, sealed_by="mppf plan")
    how, changed = _previous_seal(other)
    assert how.startswith("sealed by another installation (key ") and changed == []
    assert other[SEAL_KEY]["key_id"] in how
    assert other[SEAL_KEY]["key_id"] != seal_document(doc, load_key(), sealed_by="x")[SEAL_KEY]["key_id"]
