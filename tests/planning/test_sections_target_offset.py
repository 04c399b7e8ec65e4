"""The whole plate's over-bent target moved along its normal by a correction field (the loop's one correction of a
plate in sections): every section presses the moved target, so sections press the same correction where they meet.

A cylinder of exact development (4.2 x 2.4 m, R 20 m, steel 20 mm) split 2 x 2; its exact over-bent target is the
cylinder of the loaded radius (:mod:`tests.planning.test_sections_springback`). The field is given at the design
points as a function of their arc length ``s`` from the plate's centre and ``y``; a material point keeps its arc
length on the target, so each punch's tips must hold the target moved by the field at the punch's own ``s, y``.
"""

from __future__ import annotations

import numpy as np
import pytest
from plan_helpers import press  # noqa: F401 (fixture)
from scipy.interpolate import LinearNDInterpolator
from test_sections_springback import STEEL, T_MM, _loaded_radius, _on_target

from mppf.core.transform import apply_tf, invert_tf
from mppf.examples.analytic import cylinder_plate, hull_pose
from mppf.model.plan_options import PlanOptions
from mppf.planning.sectional import plan_plate

RADIUS_MM, LENGTH_MM, WIDTH_MM = 20000.0, 4200.0, 2400.0


def field_mm(s_mm, y_mm):
    """A smooth correction: 12 mm of bend along the plate and a 4 mm twist, mm along the target's normal."""
    return 12.0 * np.cos(np.pi * s_mm / LENGTH_MM) + 4.0 * (s_mm / LENGTH_MM) * (y_mm / WIDTH_MM) * 4.0


@pytest.fixture(scope="module")
def plans(press):
    design, flat = cylinder_plate(LENGTH_MM, WIDTH_MM, RADIUS_MM, spacing_mm=100.0)
    plate = apply_tf(invert_tf(hull_pose()), design)
    s = RADIUS_MM * np.arctan2(plate[:, 0], RADIUS_MM - plate[:, 2])
    options = PlanOptions(springback=True, material=STEEL)
    return {"plain": plan_plate(design, flat, press, T_MM, options),
            "moved": plan_plate(design, flat, press, T_MM, options, target_offset_mm=field_mm(s, plate[:, 1])),
            "loaded": _loaded_radius(RADIUS_MM)}


def test_every_section_presses_the_target_moved_by_the_field(press, plans):
    loaded = plans["loaded"]
    plain = [_on_target(press, s, loaded) for s in plans["plain"].sections]
    before = LinearNDInterpolator(np.vstack([w for w, _ in plain]), np.concatenate([h for _, h in plain]))
    assert len(plans["moved"].sections) == 4
    for section in plans["moved"].sections:
        where, height = _on_target(press, section, loaded)
        moved_by = height - before(where)
        expected = field_mm(where[:, 0], where[:, 1])
        known = np.isfinite(moved_by)
        assert known.sum() > 100, section.index
        # the offset is along the target's normal, the heights radial: the same to well under a millimetre
        assert np.abs(moved_by[known] - expected[known]).max() < 0.6, section.index


def test_the_moved_target_keeps_the_borders_smooth(press, plans):
    moved = plans["moved"].sectional
    assert moved.max_border_step_mm < 0.5 and moved.warnings == ()


def test_no_offset_is_the_plain_plan(press, plans):
    design, flat = cylinder_plate(LENGTH_MM, WIDTH_MM, RADIUS_MM, spacing_mm=100.0)
    zero = plan_plate(design, flat, press, T_MM, PlanOptions(springback=True, material=STEEL),
                      target_offset_mm=np.zeros(len(design)))
    for a, b in zip(zero.sections, plans["plain"].sections):
        assert np.allclose(a.steps[-1].upper_mm, b.steps[-1].upper_mm, equal_nan=True, atol=1e-6)


def test_a_correction_of_the_wrong_length_or_without_springback_is_refused(press):
    from mppf.core.errors import InputError

    design, flat = cylinder_plate(LENGTH_MM, WIDTH_MM, RADIUS_MM, spacing_mm=100.0)
    with pytest.raises(InputError, match="one finite value"):
        plan_plate(design, flat, press, T_MM, PlanOptions(springback=True, material=STEEL),
                   target_offset_mm=np.zeros(len(design) - 1))
    with pytest.raises(InputError, match="1 of .* are not finite"):
        plan_plate(design, flat, press, T_MM, PlanOptions(springback=True, material=STEEL),
                   target_offset_mm=np.r_[np.nan, np.zeros(len(design) - 1)])
    with pytest.raises(InputError, match="needs the springback target"):
        plan_plate(design, flat, press, T_MM, PlanOptions(springback=False, material=STEEL),
                   target_offset_mm=np.zeros(len(design)))
    small, small_flat = cylinder_plate(1500.0, 1000.0, RADIUS_MM, spacing_mm=100.0)
    with pytest.raises(InputError, match="for a plate planned in sections"):
        plan_plate(small, small_flat, press, T_MM, PlanOptions(springback=True, material=STEEL),
                   target_offset_mm=np.zeros(len(small)))
