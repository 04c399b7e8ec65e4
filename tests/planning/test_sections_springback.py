"""Sectional planning with springback: one over-bent target for the whole plate, pressed by every section.

The target's contact is what the planner presses.

Cylinders of exact development (steel 20 mm) split in two directions. Their exact over-bent target is the
cylinder of the loaded radius R' (:func:`mppf.forming.springback.loaded_curvature`), tangent to the design at
the plate's centre, with every material point at its own arc length from the centre.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.interpolate import LinearNDInterpolator

from mppf.core.transform import apply_tf, invert_tf, make_tf
from mppf.examples.analytic import cylinder_plate, hull_pose
from mppf.model.material import MATERIALS
from mppf.forming.springback import loaded_curvature
from mppf.model.plan_options import PlanOptions
from mppf.planning.contact import PlacedSurface, tip_heights
from mppf.planning.sectional import BORDER_STEP_LIMIT_MM, plan_plate
from plan_helpers import CylinderSurface, press  # noqa: F401 (fixture)

T_MM = 20.0
STEEL = MATERIALS["steel"]
TF_CYL_LOCAL = make_tf(np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]))
"""CylinderSurface (axis along u) turned so its axis runs along y, as cylinder_plate's."""

CASES = {"4.2x2.4 R20": (4200.0, 2400.0, 20000.0, [2, 2]), "7.5x2.4 R20": (7500.0, 2400.0, 20000.0, [3, 2]),
         "7.5x2.4 R6": (7500.0, 2400.0, 6000.0, [3, 2])}


def _loaded_radius(radius_mm):
    return 1.0 / float(loaded_curvature(np.array([1.0 / radius_mm]), T_MM, STEEL)[0])


@pytest.fixture(scope="module", params=list(CASES))
def case(request, press):
    """The plans of one cylinder: with springback (the target's contact) and without springback."""
    length, width, radius, counts = CASES[request.param]
    design, flat = cylinder_plate(length, width, radius, spacing_mm=100.0)
    job = plan_plate(design, flat, press, T_MM, PlanOptions(springback=True, material=STEEL))
    plain = plan_plate(design, flat, press, T_MM)
    return {"job": job, "plain": plain, "radius": radius, "loaded": _loaded_radius(radius), "counts": counts,
            "design": design, "flat": flat}


def _tf_plate_target(loaded_mm, phi):
    """Plate frame <- a CylinderSurface frame on the target (radius R', tangent at the centre) at angle phi."""
    c, s = np.cos(phi), np.sin(phi)
    on_circle = make_tf(np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]]),
                        [loaded_mm * s, 0.0, loaded_mm * (1.0 - c)])
    return on_circle @ TF_CYL_LOCAL


def _axes(press, active):
    gx, gy = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    return gx[active], gy[active]


def _target_tips(press, section, loaded_mm):
    """The exact ball contact of the whole plate's target, placed as the section places the design."""
    tf_press_plate = section.tf_press_design @ hull_pose()
    centre = apply_tf(invert_tf(tf_press_plate), np.array([[0.0, 0.0, T_MM / 2.0]]))[0]
    phi = np.arctan2(centre[0], loaded_mm - centre[2])  # the section's middle on the target
    placed = PlacedSurface(CylinderSurface(loaded_mm), tf_press_plate @ _tf_plate_target(loaded_mm, phi))
    x, y = _axes(press, section.steps[-1].active)
    up, lo = tip_heights(placed, x, y, tip_radius_mm=press.tip_radius_mm, thickness_mm=T_MM)
    return up.tip_mm, lo.tip_mm


def _on_target(press, section, loaded_mm):
    """Per active punch: the tips' mid point as (arc length along the target, y) and its height above the target."""
    final = section.steps[-1]
    x, y = _axes(press, final.active)
    mid = np.column_stack([x, y, 0.5 * (final.upper_mm[final.active] + final.lower_mm[final.active])])
    plate = apply_tf(invert_tf(section.tf_press_design @ hull_pose()), mid)
    angle = np.arctan2(plate[:, 0], loaded_mm - plate[:, 2])
    height = loaded_mm - np.hypot(plate[:, 0], loaded_mm - plate[:, 2])
    return np.column_stack([loaded_mm * angle, plate[:, 1]]), height


def _edge(press, section):
    edge = np.zeros(press.shape, dtype=bool)
    edge[[0, -1], :] = True
    edge[:, [0, -1]] = True
    return edge[section.steps[-1].active]


def test_every_section_presses_the_whole_plates_one_over_bent_target(press, case):
    job = case["job"]
    assert job.sectional.to_doc()["counts"] == case["counts"]
    for section in job.sections:
        up, lo = _target_tips(press, section, case["loaded"])
        final = section.steps[-1]
        assert np.abs(final.upper_mm[final.active] - up).max() < 0.2, section.index
        assert np.abs(final.lower_mm[final.active] - lo).max() < 0.2, section.index
    radii = job.reports.springback_doc()
    assert radii["enabled"] and "one over-bent target for the whole plate" in radii["method"]
    assert radii["loaded_radii_mm"][0] == pytest.approx(case["loaded"], rel=2e-3)
    # the over-bend is real: the strokes are far from the design's own (the plan without springback)
    assert max(np.nanmax(np.abs(a.steps[-1].upper_mm - b.steps[-1].upper_mm))
               for a, b in zip(job.sections, case["plain"].sections)) > 20.0


def test_the_recovered_target_has_no_step_at_section_borders(press, case):
    """At each section's border over plate formed before, its tips hold the same surface as the earlier section's
    (compared at the same place on the exact target, not punch by punch), and the plan carries no warning."""
    job = case["job"]
    held = [_on_target(press, s, case["loaded"]) for s in job.sections]
    compared, worst = 0, 0.0
    for k, section in enumerate(job.sections):
        where, height = held[k]
        border = _edge(press, section)
        for j in range(k):
            there = LinearNDInterpolator(*held[j])(where[border])
            found = np.isfinite(there)
            compared += int(found.sum())
            if found.any():
                worst = max(worst, float(np.abs(height[border][found] - there[found]).max()))
    assert compared > 50
    assert worst < 0.5 * BORDER_STEP_LIMIT_MM
    sectional = job.sectional.to_doc()
    assert sectional["max_border_step_mm"] < BORDER_STEP_LIMIT_MM and sectional["warnings"] == []


def test_the_marks_are_where_their_material_lies_on_the_target(press, case):
    """A mark's material point (the exact development: flat (s, y)) lies over its punch once the section has
    pressed the target: at arc length s on the cylinder of the loaded radius."""
    loaded = case["loaded"]
    for section in case["job"].sections:
        s_mm, y_mm = section.marks_flat_mm[:, 0], section.marks_flat_mm[:, 1]
        material = np.column_stack([loaded * np.sin(s_mm / loaded), y_mm, loaded * (1.0 - np.cos(s_mm / loaded))])
        formed = apply_tf(section.tf_press_design @ hull_pose(), material)
        assert np.abs(formed[:, :2] - section.marks_press_mm).max() < 2.0, section.index


def test_without_springback_the_sections_press_the_design(press, case):
    plain = case["plain"]
    assert plain.reports.springback_doc() == {"enabled": False}
    assert plain.sectional.max_border_step_mm < 0.1
