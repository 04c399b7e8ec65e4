"""The job's typed reports (mppf.model.job_reports, job_provenance, job_record): exact round trips, checked reads,
and the older version-4 layout read into the same blocks with its seal checked as written."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from driver_helpers import small_job, small_press

from mppf.core.errors import ConfigError
from mppf.core.seal import SealError, load_key, seal_document
from mppf.model.job import JOB_VERSION, job_from_dict
from mppf.model.job_provenance import (
    BatchRecord,
    LoopProvenance,
    SectionalSummary,
    SectionPiece,
    TransitionReport,
)
from mppf.model.job_reports import (
    FirstPressReport,
    InputFile,
    PlanInputs,
    PlanReports,
    PoseReport,
    RefinementReport,
    RegistrationReport,
    SpringbackReport,
    SurfaceFitReport,
    ValidationReport,
)
from mppf.planning.job import load_job, save_job

REPORTS = PlanReports(
    surface_fit=SurfaceFitReport(surface_kind="poly", surface_degree=4, surface_fit_rms_mm=0.12,
                                 surface_fit_max_mm=0.5),
    registration=RegistrationReport(method="paired", rms_mm=0.01, iterations=1, rotation_deg=90.0,
                                    ambiguous_start=False, neighbour_strain_p95_pct=0.03, area_mismatch_pct=-0.2,
                                    details={"transform": np.eye(4).tolist(), "notes": [], "residual_mm": None}),
    pose=PoseReport(tilt_x_deg=0.5, tilt_y_deg=-0.25, offset_mm=12.0, max_travel_mm=84.5,
                    travel_definition="largest |tip height - flat-plate tip height| (upper t, lower 0)"),
    validation=ValidationReport(passed=True, n_steps=2, min_gap_mm=20.0, max_neighbour_step_mm=4.5,
                                dimpling_limit_mm=5.0, upper_range_mm=(20.0, 40.0), lower_range_mm=(0.0, 20.0),
                                upper_limits_mm=(-300.0, 400.0), lower_limits_mm=(-400.0, 300.0),
                                contact_exact_fraction=1.0, contact_beyond_edge_mm=0.0),
    plate_corners_mm=np.array([[-900.0, -600.0, 0.0], [900.0, -600.0, 0.0], [900.0, 600.0, 0.0],
                               [-900.0, 600.0, 0.0]]),
    plate_size_mm=np.array([1800.0, 1200.0]), n_active=23, n_steps=2,
    inputs=PlanInputs(design=InputFile(path="d.csv", sha256="ab" * 32), units="mm"),
    springback=SpringbackReport(enabled=True, method="principal arcs", target_radii_mm=(4000.0, None),
                                loaded_radii_mm=(3500.0, None), directions_uv=((1.0, 0.0), (0.0, 1.0)),
                                refinement=RefinementReport(virtual_cycles=2, predicted_max_mm=0.1,
                                                            history_mm=(3.0, 0.4, 0.1)),
                                first_press=FirstPressReport(yield_uncertainty_pct=10.0, nominal_yield_mpa=235.0,
                                                             planned_yield_mpa=211.5, rule="weakest")),
)


def test_every_block_reads_back_to_the_same_document():
    doc = json.loads(json.dumps(REPORTS.to_doc()))
    back = PlanReports.from_doc(doc, "job:")
    assert json.dumps(back.to_doc()) == json.dumps(doc)  # same keys, order and numbers: the same bytes
    assert back.max_travel_mm == 84.5 and back.design_sha256 == "ab" * 32
    assert back.validation.upper_range_mm == (20.0, 40.0) and back.springback.first_press.planned_yield_mpa == 211.5
    assert back.registration.details["notes"] == [] and "residual_mm" in doc["registration"]
    assert doc["planner"]["surface_degree"] == 4 and isinstance(doc["n_active"], int)
    np.testing.assert_array_equal(back.plate_corners_mm, REPORTS.plate_corners_mm)
    for block in (SectionalSummary(n_sections=6, counts=(3, 2), plate_size_mm=np.array([9000.0, 3000.0]),
                                   warnings=("section 2: steps",)),
                  TransitionReport(zone_mm=450.0, blended_punches=40, border_step_mm=0.02),
                  BatchRecord(key="k" * 64, row={"plate": "p", "steps": 3}),
                  LoopProvenance(plate_id="K1", cycle=3, corrects_job_sha256="0" * 64),
                  SectionPiece(index=2, of=6, plate_centre_mm=np.array([150.0, 0.0]),
                               own_weight=np.array([[np.nan, 1.0], [0.5, 1.0]]))):
        doc = json.loads(json.dumps(block.to_doc()))
        assert json.dumps(type(block).from_doc(doc, "job: block").to_doc()) == json.dumps(doc)
    assert np.isnan(SectionPiece.from_doc({"own_weight": [[None, 1.0]]}).own_weight[0, 0])


@pytest.mark.parametrize("doc, message", [
    ({"pose": {"max_travel_mm": "84"}}, 'job.json: pose max_travel_mm is "84", not a finite number'),
    ({"validation": {"passed": 1}}, "job.json: validation passed is 1, not true or false"),
    ({"validation": []}, r"job.json: validation is \[\], not an object"),
    ({"n_steps": 2.5}, "job.json: n_steps is 2.5, not a whole number"),
    ({"plate_corners_mm": [[0, 0, 0]]}, r"job.json: plate_corners_mm is \[\[0, 0, 0\]\], not 4 x 3 finite numbers"),
    ({"springback": {"first_press": {"rule": 3}}}, "job.json: springback first_press rule is 3, not a string"),
    ({"registration": {"neighbour_strain_p95_pct": True}}, "registration neighbour_strain_p95_pct is true"),
    ({"inputs": {"design": "d.csv"}}, 'job.json: inputs design is "d.csv", not an object'),
])
def test_a_report_of_the_wrong_type_is_one_clear_config_error(doc, message):
    with pytest.raises(ConfigError, match=message) as info:
        PlanReports.from_doc(doc, "job.json:")
    assert "re-plan the plate" in info.value.hint


def test_the_job_blocks_are_checked_where_the_job_is_read():
    doc = small_job(small_press()).to_dict()
    with pytest.raises(ConfigError, match='job.json: loop cycle is "3", not a whole number'):
        job_from_dict({**doc, "loop": {"cycle": "3"}}, "job.json")
    with pytest.raises(ConfigError, match="job.json: sectional warnings is"):
        job_from_dict({**doc, "sectional": {"warnings": "none"}}, "job.json")


def _version_4(job) -> dict:
    """The document an mppf before the typed reports wrote: version 4, the registration's keys in its own order,
    its nulls kept, every report a plain object."""
    doc = job.to_dict()
    doc["version"] = 4
    doc["registration"] = {"rms_mm": 0.01, "iterations": 1, "method": "paired", "residual_mm": None,
                           "rotation_deg": 90.0, "neighbour_strain_p95_pct": 0.03}
    doc["validation"] = {**doc["validation"], "min_gap_mm": None}
    doc["batch"] = {"key": "k" * 64, "row": {"plate": "p"}}
    return doc


def test_a_version_4_job_is_read_with_its_seal_checked_as_written(tmp_path):
    job = dataclasses.replace(small_job(small_press()), reports=REPORTS)
    path = tmp_path / "old.json"
    path.write_text(json.dumps(seal_document(_version_4(job), load_key(), sealed_by="mppf plan"), indent=1))
    old = load_job(path)  # the seal matches the document as written (nulls, key order), not a re-serialisation
    assert old.reports.registration.method == "paired" and old.reports.registration.details == {"residual_mm": None}
    assert old.reports.validation.min_gap_mm is None and old.batch.key == "k" * 64
    assert old.seal.sealed_by == "mppf plan" and old.reports.max_travel_mm == 84.5
    # written again by this mppf: version 5, sealed anew, read back to the same bytes
    again = load_job(save_job(old, tmp_path / "new.json"))
    assert json.loads((tmp_path / "new.json").read_text())["version"] == JOB_VERSION == 5
    assert again.sha256() == old.sha256() and again.reports.to_doc() == old.reports.to_doc()
    # an edited version-4 job is refused by its seal, naming the part
    doc = json.loads(path.read_text())
    doc["validation"]["passed"] = False
    path.write_text(json.dumps(doc, indent=1))
    with pytest.raises(SealError, match="changed: validation"):
        load_job(path)
