"""The job file (``mppf/planning/job.py``): layout, round trip, atomic save and every load error."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mppf.core.errors import ConfigError, InputError
from mppf.model.job import JOB_FORMAT, JOB_VERSION, Job, job_from_dict
from mppf.model.job_reports import InputFile, PlanInputs, PlanReports, RegistrationReport
from mppf.model.job_parts import StepStrokes
from mppf.planning.job import load_job, save_job
from mppf.model.press import example_press_path, load_press
from mppf.core.transform import make_tf

PRESS = load_press(example_press_path())
T = 12.0


def _job(n_steps: int = 2) -> Job:
    """A small hand-made job: a 4 x 5 block of active punches in the middle of the bed."""
    rng = np.random.default_rng(7)
    active = np.zeros(PRESS.shape, dtype=bool)
    active[6:10, 10:15] = True
    steps = []
    for k in range(1, n_steps + 1):
        lower = np.where(active, k * rng.uniform(-5.0, 5.0, PRESS.shape), np.nan)
        upper = np.where(active, lower + T + rng.uniform(0.0, 1.0, PRESS.shape), np.nan)
        steps.append(StepStrokes(upper_mm=upper, lower_mm=lower, active=active))
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    return Job(press=PRESS, thickness_mm=T, steps=steps, tf_press_design=make_tf(rot, [1.0, 2.0, 3.5]),
               tf_press_flat=make_tf(translation=[0.0, 0.0, T / 2]),
               reports=PlanReports(registration=RegistrationReport(method="paired"),
                                   inputs=PlanInputs(design=InputFile(sha256="ab"))))


def test_document_layout():
    job = _job()
    doc = json.loads(job.to_json())
    assert doc["format"] == JOB_FORMAT == "mppf-job" and doc["version"] == JOB_VERSION == 5
    assert doc["press"] == PRESS.to_dict()
    assert doc["thickness_mm"] == T
    # 4 x 4 row-major nested lists: the translation is the last column of the first three rows
    assert [row[3] for row in doc["tf_press_design"][:3]] == [1.0, 2.0, 3.5]
    assert doc["tf_press_design"][0][:3] == [0.0, -1.0, 0.0]
    assert doc["tf_press_flat"][2][3] == T / 2 and doc["tf_press_flat"][3] == [0.0, 0.0, 0.0, 1.0]
    assert doc["punch_x_mm"] == PRESS.punch_x_mm.tolist() and len(doc["punch_x_mm"]) == PRESS.cols
    assert doc["punch_y_mm"] == PRESS.punch_y_mm.tolist() and len(doc["punch_y_mm"]) == PRESS.rows
    assert [s["index"] for s in doc["steps"]] == [1, 2]
    step = doc["steps"][0]
    for key in ("upper_mm", "lower_mm", "active"):
        assert len(step[key]) == PRESS.rows and all(len(row) == PRESS.cols for row in step[key])
    assert step["upper_mm"][0][0] is None and step["lower_mm"][0][0] is None and step["active"][0][0] is False
    assert step["upper_mm"][7][12] == round(float(job.steps[0].upper_mm[7, 12]), 4)
    assert step["active"][7][12] is True
    assert doc["registration"] == {"method": "paired"} and doc["inputs"]["design"]["sha256"] == "ab"


def test_round_trip_and_hash(tmp_path):
    job = _job()
    path = save_job(job, tmp_path / "job.json")
    assert not (tmp_path / "job.json.tmp").exists()
    back = load_job(path)
    assert back.press == PRESS and back.thickness_mm == T
    np.testing.assert_allclose(back.tf_press_design, job.tf_press_design)
    np.testing.assert_allclose(back.tf_press_flat, job.tf_press_flat)
    np.testing.assert_array_equal(back.punch_x_mm, job.punch_x_mm)
    for a, b in zip(back.steps, job.steps):
        np.testing.assert_array_equal(a.active, b.active)
        np.testing.assert_allclose(a.upper_mm, b.upper_mm, atol=5e-5, equal_nan=True)
        np.testing.assert_allclose(a.lower_mm, b.lower_mm, atol=5e-5, equal_nan=True)
    assert back.reports.to_doc() == job.reports.to_doc() and back.seal == job.seal is not None
    # the rounded file reads back to the same document, so the hash is stable
    assert back.sha256() == job.sha256() == load_job(save_job(back, tmp_path / "again.json")).sha256()


def test_setpoints_park_inactive_punches():
    step = _job(1).steps[0]
    upper, lower = step.setpoints_mm(PRESS)
    assert np.all(np.isfinite(upper)) and np.all(np.isfinite(lower))
    assert np.all(upper[~step.active] == PRESS.upper.park_mm)
    assert np.all(lower[~step.active] == PRESS.lower.park_mm)
    np.testing.assert_array_equal(upper[step.active], step.upper_mm[step.active])


def test_non_finite_stroke_is_never_written():
    job = _job(1)
    job.steps[0].upper_mm[7, 12] = np.inf
    doc = json.loads(job.to_json())
    assert doc["steps"][0]["upper_mm"][7][12] is None
    with pytest.raises(ConfigError, match="active punches without a stroke"):
        job_from_dict(doc)


def _doc():
    return json.loads(_job().to_json())


def _set(doc, path, value):
    target = doc
    for key in path[:-1]:
        target = target[key]
    if value is KeyError:
        del target[path[-1]]
    else:
        target[path[-1]] = value
    return doc


@pytest.mark.parametrize(
    "path, value, message",
    [
        (("format",), "something", "not an mppf job file (format 'something')"),
        (("version",), 6, "job file version 6 is not supported"),
        (("press",), KeyError, "missing key 'press'"),
        (("thickness_mm",), KeyError, "missing key 'thickness_mm'"),
        (("steps",), KeyError, "missing key 'steps'"),
        (("thickness_mm",), 0, "job.json: thickness_mm must be above 0 mm, got 0"),
        (("thickness_mm",), "12", "job.json: thickness_mm must be a number, got '12'"),
        (("thickness_mm",), True, "job.json: thickness_mm must be a number, got True"),
        (("steps",), [], "'steps' must be a non-empty list"),
        (("steps",), {"1": 2}, "'steps' must be a non-empty list"),
        (("steps", 0, "active"), KeyError, "step 1 needs upper_mm, lower_mm and active"),
        (("steps", 1, "upper_mm"), [[1.0, 2.0]], "step 2 upper_mm has shape (1, 2), the press has (16, 24)"),
        (("steps", 0, "lower_mm", 3), ["x"] * 24, "step 1 lower_mm must be a grid of numbers or null"),
        (("steps", 0, "upper_mm", 7, 12), None, "step 1 has active punches without a stroke (null)"),
        (("press", "matrix", "rows"), "16", "[press]: [matrix] rows must be a whole number"),
        (("tf_press_design",), [[1, 0], [0, 1]], "job.json: tf_press_design must be a finite 4x4 matrix"),
        (("tf_press_flat",), "eye", "job.json: tf_press_flat"),
        (("punch_x_mm",), [0.0, 150.0], "punch_x_mm must hold 24 finite numbers"),
        (("punch_y_mm",), ["a"] * 16, "punch_y_mm must be a list of numbers"),
        (("punch_y_mm",), [None] * 16, "punch_y_mm must hold 16 finite numbers"),
    ],
)
def test_each_bad_document_is_a_config_error(path, value, message):
    with pytest.raises(ConfigError) as info:
        job_from_dict(_set(_doc(), path, value), source="job.json")
    assert message in info.value.message
    assert info.value.exit_code == 2


def test_not_a_document():
    with pytest.raises(ConfigError, match="not an mppf job file"):
        job_from_dict([1, 2, 3])


def test_load_job_file_errors(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        load_job(tmp_path / "missing.json")
    with pytest.raises(InputError, match="cannot be read"):
        load_job(tmp_path)
    broken = tmp_path / "broken.json"
    broken.write_text('{"format": "mppf-job",\n "version": ')
    with pytest.raises(ConfigError, match="line 2: not valid JSON"):
        load_job(broken)
    binary = tmp_path / "binary.json"
    binary.write_bytes(b"\xff\xfe\x00\x01")
    with pytest.raises(InputError, match="cannot be read"):
        load_job(binary)


def test_save_job_refuses_unwritable_paths_and_keeps_the_old_file(tmp_path):
    with pytest.raises(InputError, match="cannot write job file"):
        save_job(_job(), tmp_path / "no" / "such" / "folder" / "job.json")
    folder = tmp_path / "a_folder"
    folder.mkdir()
    with pytest.raises(InputError, match="cannot write job file"):
        save_job(_job(), folder)
    assert folder.is_dir()


def test_plate_layout_round_trips_and_version_1_jobs_are_read(tmp_path):
    from mppf.model.job_parts import PlateLayout
    from mppf.model.material import Material

    net = np.array([[-500.0, -300.0], [500.0, -300.0], [500.0, 300.0], [-500.0, 300.0]])
    mid = np.where(PRESS.punch_x_mm[None, :] > 0, 5.0, np.nan) * np.ones(PRESS.shape)
    layout = PlateLayout(net * 1.2, net, margin_mm=100.0, design_mid_mm=mid, material=Material(yield_stress_mpa=355.0))
    assert np.allclose(layout.reference_corner_mm, [-600.0, -360.0])  # the corner of the plate as cut
    job = _job()
    job.layout = layout
    back = load_job(save_job(job, tmp_path / "job.json"))
    assert np.allclose(back.layout.outline_mm, net * 1.2) and np.allclose(back.layout.net_outline_mm, net)
    assert back.layout.margin_mm == 100.0 and back.layout.material.yield_stress_mpa == 355.0
    np.testing.assert_array_equal(np.isnan(back.layout.design_mid_mm), np.isnan(mid))
    # a version-1 job kept the layout in loose top-level keys
    doc = json.loads(job.to_json())
    plate = doc.pop("plate")
    doc.update(version=1, plate_outline_mm=plate["outline_mm"], net_outline_mm=plate["net_outline_mm"],
               margin_mm=plate["margin_mm"], design_mid_mm=plate["design_mid_mm"], material=plate["material"])
    old = job_from_dict(doc)
    assert np.allclose(old.layout.outline_mm, back.layout.outline_mm) and old.layout.margin_mm == 100.0
    assert np.allclose(old.layout.reference_corner_mm, [-600.0, -360.0])
    assert old.reports.registration == RegistrationReport(method="paired", details={})
    # an old job without an outline has no layout
    for key in ("plate_outline_mm", "net_outline_mm", "margin_mm", "design_mid_mm", "material"):
        doc.pop(key)
    assert job_from_dict(doc).layout is None
