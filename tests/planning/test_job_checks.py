"""The plan re-derived (mppf.planning.job_checks): placements, marks, sections and steps that do not follow are refused."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mppf.core.errors import ConfigError
from mppf.core.transform import make_tf
from mppf.examples.analytic import cylinder_plate
from mppf.model.press import example_press_path, load_press
from mppf.planning.job_checks import check_plan
from mppf.planning.sectional import plan_plate
from mppf.planning.validate import validate_job


@pytest.fixture(scope="module")
def press():
    return load_press(example_press_path())


@pytest.fixture(scope="module")
def sectional(press):
    design, flat = cylinder_plate(7500.0, 2400.0, 20000.0)
    return plan_plate(design, flat, press, 20.0)


@pytest.fixture(scope="module")
def single(press):
    design, flat = cylinder_plate(3000.0, 2000.0, 8000.0, spacing_mm=100.0)
    return plan_plate(design, flat, press, 20.0)


def _with_section(job, k, **changes):
    sections = list(job.sections)
    sections[k - 1] = dataclasses.replace(sections[k - 1], **changes)
    return dataclasses.replace(job, sections=sections)


def test_planned_jobs_pass(sectional, single):
    assert len(sectional.sections) == 6
    check_plan(sectional)
    check_plan(single)
    validate_job(sectional)


def test_each_placement_edit_is_refused_naming_section_and_distance(sectional):
    s2, s3 = sectional.sections[1], sectional.sections[2]
    cases = [
        (_with_section(sectional, 2, plate_centre_mm=s2.plate_centre_mm + [1000.0, 0.0]),
         "section 2 plate centre (3100.0, -75.0) mm and flat transform do not place the plate as section 1 does"),
        (_with_section(sectional, 3, marks_press_mm=s3.marks_press_mm + 300.0), "section 3 marks on the bed"),
        (_with_section(sectional, 3, marks_plate_mm=s3.marks_plate_mm + 300.0),
         "section 3 marks in plate coordinates"),
        (_with_section(sectional, 2, tf_press_flat=make_tf(translation=[500.0, 0.0, 0.0]) @ s2.tf_press_flat),
         "section 2 plate centre"),
        (_with_section(sectional, 3, mark_punches=s3.mark_punches + [[0, 1], [0, 0]]), "section 3 mark"),
        (dataclasses.replace(sectional, sections=sectional.sections[:-1]),
         "the plan has 6 section(s), the job holds 5"),
        (dataclasses.replace(sectional, sections=sectional.sections[:-1] + [sectional.sections[0]]),
         "appear more than once"),
    ]
    for job, words in cases:
        with pytest.raises(ConfigError) as info:
            check_plan(job)
        assert words in info.value.message, info.value.message
        assert "nothing was sent to the press" in info.value.message


def test_repeated_or_removed_steps_and_a_failed_validation_are_refused(single):
    steps = single.steps
    doubled = dataclasses.replace(single, steps=[steps[0]] + steps)
    with pytest.raises(ConfigError, match="step 2 repeats step 1"):
        check_plan(doubled)
    if len(steps) > 1:
        with pytest.raises(ConfigError, match=r"n_steps is \d+ but the job holds"):
            check_plan(dataclasses.replace(single, steps=steps[:-1]))
    failed = dataclasses.replace(single, reports=dataclasses.replace(
        single.reports, validation=dataclasses.replace(single.reports.validation, passed=False)))
    with pytest.raises(ConfigError, match="validation did not pass"):
        check_plan(failed)


def test_an_outline_that_is_not_the_net_outline_grown_by_the_margin(single):
    layout = dataclasses.replace(single.layout, outline_mm=single.layout.outline_mm + [1000.0, 0.0])
    with pytest.raises(ConfigError, match="outline as cut is 1000.00 mm away"):
        check_plan(dataclasses.replace(single, layout=layout))
    assert np.isfinite(single.layout.margin_mm)


def test_punch_axes_that_are_not_the_presss_are_refused(single):
    moved = dataclasses.replace(single, punch_x_mm=single.punch_x_mm + 5.0)
    with pytest.raises(ConfigError, match="punch_x_mm is 5.00 mm away from the punch axes of its press"):
        check_plan(moved)
