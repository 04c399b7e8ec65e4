"""Issue 38 against a running simulated PLC: a job edited after planning never reaches the press.

Each edit is refused before anything is written (no write request reaches the PLC, nothing moves):
by the seal, and, sealed again by someone who has the key, by the machine's press, the plan's
re-derived checks or the job validator.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from driver_helpers import install_press, running_sim, small_job, small_press
from mppf.drivers.audit import AuditLog

from mppf.cli import main
from mppf.core.seal import load_key, seal_document
from mppf.planning.job import save_job


@pytest.fixture
def press():
    return small_press()


sim = pytest.fixture(running_sim, name="sim")


home = pytest.fixture(install_press, name="home", autouse=True)


def _pair(doc, mm):
    for key in ("upper_mm", "lower_mm"):
        doc["steps"][-1][key][1][2] += mm


def _dimpling(doc):
    doc["press"]["forming"]["max_neighbour_diff_mm"] = 300.0
    _pair(doc, 100.0)


def _validation(doc):
    doc["validation"] = {"passed": False, "n_steps": len(doc["steps"])}


EDITS = {
    "pair +2 mm": (lambda d: _pair(d, 2.0), "changed: step 2", None),
    "dimpling limit 300, pair +100 mm": (_dimpling, "changed: press, step 2",
                                         "[forming] max_neighbour_diff_mm is 300.0 in the job, 30.0 in"),
    "pitch 150 -> 140": (lambda d: d["press"]["matrix"].update(pitch_x_mm=140.0), "changed: press",
                         "[matrix] pitch_x_mm is 140.0 in the job, 150.0 in"),
    "lower park 250": (lambda d: d["press"]["lower"].update(park_mm=250.0), "changed: press",
                       "[lower] park_mm is 250.0 in the job, -400.0 in"),
    "step 1 twice": (lambda d: d["steps"].insert(0, d["steps"][0]), "changed: number of steps, step 2, step 3 (added)",
                     "step 2 repeats step 1"),
    "validation failed": (_validation, "changed: validation", "the planner's validation did not pass"),
}


# Every edit as it was made, and sealed again by someone who has the key: then the checks against the machine's press
# and the plan must refuse it (an edit within every limit is left out there: only the seal can tell it).
CASES = [pytest.param(name, resealed, id=f"{name}-{'sealed again' if resealed else 'as edited'}")
         for name in sorted(EDITS) for resealed in (False, True) if not (resealed and EDITS[name][2] is None)]


@pytest.mark.parametrize(("name", "resealed"), CASES)
def test_an_edited_job_writes_nothing_to_the_plc(name, resealed, tmp_path, press, sim, capsys):
    edit, sealed_words, resealed_words = EDITS[name]
    doc = json.loads(save_job(small_job(press, n_steps=2), tmp_path / "job.json").read_text())
    edit(doc)
    if resealed:
        doc = seal_document(doc, load_key(), sealed_by="someone who has the key")
    path = tmp_path / "edited.json"
    path.write_text(json.dumps(doc, indent=1))
    before = sim.actual_positions_mm()
    code = main(["press", str(path), "--plc", sim.url, "--yes", "--audit", str(tmp_path / "audit.sqlite")])
    err = " ".join(capsys.readouterr().err.split())
    assert code == 2 and (resealed_words if resealed else sealed_words) in err, err
    assert "Traceback" not in err
    assert sim.server.master_writes == 0 and sim.state() == "IDLE"
    with AuditLog(tmp_path / "audit.sqlite") as log:  # the refusal is kept: the seal's, or the validator's
        refused = [(e.action, e.outcome) for e in log.entries()]
    assert refused == [("limits" if resealed else "seal", "refused")], refused
    for a, b in zip(sim.actual_positions_mm(), before):
        np.testing.assert_array_equal(a, b)
