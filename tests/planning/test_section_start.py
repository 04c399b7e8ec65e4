"""A later section's steps start from the plate the earlier sections formed (mppf.planning.section_start)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mppf.core.errors import LimitError
from mppf.core.grid import largest_neighbour_difference
from mppf.examples.analytic import cylinder_plate
from mppf.model.material import MATERIALS
from mppf.model.plan_options import PlanOptions
from mppf.model.press import example_press_path, load_press
from mppf.planning.section_start import (
    LAWFUL_FROM_FLAT,
    continue_heights,
    formed_punches,
    section_start,
    steps_from,
)
from mppf.planning.sectional import from_formed_plate, plan_plate
from mppf.planning.validate import validate_job, validate_steps

THICKNESS_MM = 20.0


@pytest.fixture(scope="module")
def press():
    return load_press(example_press_path())


@pytest.fixture(scope="module")
def job(press):
    """A 3.9 x 1.5 m cylinder of R 10 m with springback (two sections along x), its second from the formed plate."""
    design, flat = cylinder_plate(3900.0, 1500.0, 10000.0, spacing_mm=100.0)
    planned = plan_plate(design, flat, press, THICKNESS_MM, PlanOptions(material=MATERIALS["steel"], springback=True))
    assert planned.sections is not None and len(planned.sections) == 2
    assert all(s.transition.start_share is None for s in planned.sections)  # the planner presses from flat
    started = from_formed_plate(planned)
    assert started.sectional.n_steps_total == sum(len(s.steps) for s in started.sections)
    for a, b in zip(planned.sections, started.sections):  # the final strokes stay
        assert np.allclose(a.steps[-1].lower_mm, b.steps[-1].lower_mm, equal_nan=True, rtol=0.0, atol=1e-9)
    return started


def test_a_plane_is_continued_as_itself_and_a_curve_by_its_tangent():
    rows, cols = np.mgrid[0:6, 0:10].astype(float)
    known = cols < 5
    active = np.ones(known.shape, dtype=bool)
    active[0, 9] = False
    plane = 3.0 + 2.0 * cols + 0.5 * rows
    assert np.allclose(continue_heights(np.where(known, plane, np.nan), known, active)[active], plane[active])
    curve = 0.1 * cols**2
    out = continue_heights(np.where(known, curve, np.nan), known, active)
    assert np.allclose(out[2, 5:], curve[2, 4] + (curve[2, 4] - curve[2, 3]) * np.arange(1, 6))  # its last chord
    assert np.isnan(out[0, 9])


def test_the_second_section_starts_where_the_first_left_the_plate(press, job):
    first, second = job.sections
    assert first.transition.start_share is None and section_start(job.sections, 0, press, THICKNESS_MM) is None
    share = second.transition.start_share
    assert share is not None and 0.0 < share <= 1.0
    start = section_start(job.sections, 1, press, THICKNESS_MM)
    final = second.steps[-1]
    formed = formed_punches(press, -second.plate_centre_mm, final.active,
                            [(-first.plate_centre_mm, first.steps[-1].active)])
    assert 0 < formed.sum() < final.active.sum()
    # every step is k/N of the way from the start: each punch moves one way, the formed part is not bent back
    n = len(second.steps)
    for k, step in enumerate(second.steps, start=1):
        for got, begin, end in ((step.upper_mm, start[0], final.upper_mm), (step.lower_mm, start[1], final.lower_mm)):
            assert np.allclose(got[final.active], (begin + k / n * (end - begin))[final.active])
    # over the formed punches the start is the design (its plane the final strokes'), this share of the way from flat
    mid = 0.5 * (start[0] + start[1])
    bent = mid - share * second.layout.design_mid_mm
    gx, gy = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    coef = np.linalg.lstsq(np.column_stack([np.ones(formed.sum()), gx[formed], gy[formed]]), bent[formed],
                           rcond=None)[0]
    assert np.abs(bent[formed] - (coef[0] + coef[1] * gx[formed] + coef[2] * gy[formed])).max() < 1e-6
    # the first steps are lawful from the flat plate too (the PLC's rule between sections)
    for step in second.steps[:LAWFUL_FROM_FLAT]:
        assert largest_neighbour_difference(step.lower_mm, final.active) <= press.max_neighbour_diff_mm + 1e-9


def test_the_validator_checks_a_later_sections_steps_from_its_start(press, job):
    validate_job(job)
    second = job.sections[1]
    start = section_start(job.sections, 1, press, THICKNESS_MM)
    validate_steps(second.steps, press, THICKNESS_MM, start=start)
    # the same steps after a first step that moved every punch a little the other way are refused (a reversal)
    final = second.steps[-1]
    back = steps_from(start, start[0] - 0.2 * (final.upper_mm - start[0]), start[1] - 0.2 * (final.lower_mm - start[1]),
                      final.active, THICKNESS_MM, 1)
    with pytest.raises(LimitError, match="reverses direction"):
        validate_steps(back + list(second.steps), press, THICKNESS_MM, start=start)


def test_without_a_share_the_section_starts_from_flat(press, job):
    second = job.sections[1]
    plain = dataclasses.replace(second, transition=dataclasses.replace(second.transition, start_share=None))
    assert section_start([job.sections[0], plain], 1, press, THICKNESS_MM) is None
