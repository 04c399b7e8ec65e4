"""The one job validator (mppf/planning/validate.py): every class of bad or tampered job, punch by punch."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from mppf.core.errors import ConfigError, InputError, LimitError
from mppf.model.job import Job
from mppf.model.job_parts import StepStrokes
from mppf.planning.job import save_job
from mppf.model.press import example_press_path, load_press
from mppf.planning.job import load_job
from mppf.planning.validate import check_job_document, check_setpoints, validate_job, validate_steps

PRESS = load_press(example_press_path())
T = 20.0


def _flat_step(active=None):
    active = np.ones(PRESS.shape, bool) if active is None else active
    return StepStrokes(upper_mm=np.where(active, T, np.nan), lower_mm=np.where(active, 0.0, np.nan),
                       active=active)


def test_validation_lists_limit_gap_and_reversal_problems():
    bad = _flat_step()
    bad.upper_mm[2, 3] = 500.0
    with pytest.raises(LimitError, match=r"upper punch \(row 3, col 4\): stroke 500.00 mm beyond the stroke limits "
                                         r"-300..400"):
        validate_steps([bad], PRESS, T)
    squeezed = _flat_step()
    squeezed.upper_mm[4, 7] = T - 0.5
    with pytest.raises(LimitError, match=r"punch pair \(row 5, col 8\): tip gap 19.50 mm < thickness 20"):
        validate_steps([squeezed], PRESS, T)
    there = _flat_step()
    there.lower_mm[1, 1] = there.upper_mm[1, 1] = 10.0
    there.upper_mm[1, 1] = 30.0
    back = _flat_step()
    with pytest.raises(LimitError, match=r"step 2 upper punch \(row 2, col 2\) reverses direction: moves -10.00 mm"):
        validate_steps([there, back], PRESS, T)
    # inactive punches are not checked
    parked = _flat_step()
    parked.active[0, 0] = False
    parked.upper_mm[0, 0] = np.nan
    assert validate_steps([parked], PRESS, T)["passed"]


def test_the_press_may_name_its_punches_from_0():
    zero = dataclasses.replace(PRESS, label_base=0)
    bad = _flat_step()
    bad.upper_mm[2, 3] = 500.0
    with pytest.raises(LimitError, match=r"upper punch \(row 2, col 3\)"):
        validate_steps([bad], zero, T)


def test_a_dimpling_step_names_both_punches_the_change_and_the_limit():
    step = _flat_step()
    step.upper_mm[3, 3] += 250.0  # one punch 250 mm above its neighbours
    step.lower_mm[3, 3] += 250.0
    with pytest.raises(LimitError) as info:
        validate_steps([step], PRESS, T)
    assert ("step 1 upper punches (row 4, col 3) and (row 4, col 4): the height difference changes by +250.00 mm, "
            "dimpling limit 30 mm") in info.value.message
    assert "8 problem(s)" in info.value.message  # 4 neighbours x 2 matrices


def test_a_parked_punch_with_a_stroke_and_a_plate_too_thick_are_refused(tmp_path):
    doc = _job_doc(tmp_path)
    doc["steps"][0]["active"][0][0] = False
    doc["steps"][0]["upper_mm"][0][0] = 100.0  # a stroke that would silently not be pressed
    with pytest.raises(ConfigError, match=r"step 1 upper punch \(row 1, col 1\) is parked \(not active\) but has a "
                                          r"stroke 100.00 mm; parked punches stand at park 400.0 mm"):
        check_job_document(doc)
    with pytest.raises(LimitError, match="thickness 60 mm is above .* max_thickness_mm 50 mm"):
        validate_steps([_flat_step()], PRESS, 60.0)


def test_setpoints_are_numbers_within_the_press_and_plc_limits_and_parked_at_park():
    upper, lower = np.full(PRESS.shape, 50.0), np.full(PRESS.shape, 10.0)
    grids = check_setpoints(upper, lower, PRESS, {"upper": (-300.0, 100.0), "lower": (-400.0, 300.0)})
    assert grids["upper"].dtype == float
    with pytest.raises(InputError, match="upper setpoints must be numbers .* array of bool"):
        check_setpoints(np.ones(PRESS.shape, bool), lower, PRESS)
    with pytest.raises(InputError, match="array of <U"):
        check_setpoints(np.full(PRESS.shape, "1.0"), lower, PRESS)
    with pytest.raises(InputError, match="shape"):
        check_setpoints(upper[:3], lower, PRESS)
    high = upper.copy()
    high[1, 2] = 150.0
    with pytest.raises(LimitError, match=r"1 setpoint\(s\) beyond the stroke limits, nothing was written to the "
                                         r"PLC: upper punch \(row 2, col 3\) = 150.00 mm, limits -300.00..100.00 mm"):
        check_setpoints(high, lower, PRESS, {"upper": (-300.0, 100.0), "lower": (-400.0, 300.0)})
    active = np.ones(PRESS.shape, bool)
    active[0, 0] = False
    with pytest.raises(LimitError, match=r"parked upper punch \(row 1, col 1\) = 50.00 mm, park 400 mm"):
        check_setpoints(upper, lower, PRESS, active=active)


def _job_doc(tmp_path) -> dict:
    job = Job(press=PRESS, thickness_mm=T, steps=[_flat_step()])
    return json.loads(save_job(job, tmp_path / "job.json").read_text())


@pytest.mark.parametrize("value, shown", [(True, "true"), ("12.5", '"12.5"'), (float("nan"), "NaN"),
                                          (float("inf"), "Infinity"), ([1], "[1]")])
def test_a_stroke_that_is_not_a_finite_number_is_refused_not_read_as_one(tmp_path, value, shown):
    doc = _job_doc(tmp_path)
    doc["steps"][0]["upper_mm"][1][2] = value
    with pytest.raises(ConfigError) as info:
        check_job_document(doc, "job.json")
    assert f"step 1 upper punch (row 2, col 3): stroke {shown} is not a finite number of mm" in info.value.message
    path = tmp_path / "tampered.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(ConfigError, match="the job holds values that cannot be pressed"):
        load_job(path)


def test_activity_flags_and_the_thickness_must_be_what_they_claim(tmp_path):
    doc = _job_doc(tmp_path)
    doc["steps"][0]["active"][0][1] = 1
    doc["thickness_mm"] = True
    with pytest.raises(ConfigError) as info:
        check_job_document(doc)
    assert "thickness_mm is true, not a finite number of mm" in info.value.message
    assert "step 1 punch (row 1, col 2): active is 1, not true or false" in info.value.message


def test_a_job_is_checked_against_the_press_file_and_the_plc(tmp_path):
    job = Job(press=PRESS, thickness_mm=T, steps=[_flat_step()])
    assert validate_job(job, press_file=PRESS)["passed"]
    other = dataclasses.replace(PRESS, max_neighbour_diff_mm=25.0)
    with pytest.raises(ConfigError, match=r"another press than press.toml: \[forming\] max_neighbour_diff_mm is 30.0 "
                                          r"in the job, 25.0 in press.toml"):
        validate_job(job, press_file=other, press_source="press.toml")
    with pytest.raises(ConfigError, match="the job is for 16 x 24 punches, the PLC drives 4 x 6"):
        validate_job(job, plc_shape=(4, 6))
    with pytest.raises(LimitError,
                       match=r"\[upper\] max_mm 400 mm of the job's press is beyond the PLC's limit 350 mm"):
        validate_job(job, plc_shape=PRESS.shape, plc_limits={"upper": (-300.0, 350.0), "lower": (-400.0, 300.0)})


def test_a_planned_style_job_passes_and_reports_its_figures():
    steps = []
    active = np.ones(PRESS.shape, bool)
    for k in (1, 2):
        lower = np.full(PRESS.shape, 10.0 * k)
        steps.append(StepStrokes(lower + T, lower, active))
    report = validate_job(Job(press=PRESS, thickness_mm=T, steps=steps), plc_shape=PRESS.shape,
                          plc_limits={"upper": (-300.0, 400.0), "lower": (-400.0, 300.0)})
    assert report["passed"] and report["n_steps"] == 2 and report["min_gap_mm"] == pytest.approx(T)
    assert report["lower_range_mm"] == [20.0, 20.0]
