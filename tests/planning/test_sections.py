"""Sectional planning: a 7.5 x 2.4 m cylinder (exact development) and a twisted plate on the 3.45 x 2.25 m bed."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy.interpolate import LinearNDInterpolator

from mppf.core.errors import ConfigError, LimitError
from mppf.core.transform import apply_tf, invert_tf, make_tf
from mppf.examples import analytic
from mppf.examples.analytic import cylinder_plate, hull_pose, twisted_plate
from mppf.geometry.unfold import unfold
from mppf.model.plan_options import PlanOptions
from mppf.planning.contact import PlacedSurface, tip_heights
from mppf.model.job import JOB_VERSION, SECTIONS_VERSION, job_from_dict
from mppf.planning.placement import place_flat
from mppf.planning.plan import plan_job
from mppf.planning.sectional import plan_plate, plan_sectional
from mppf.planning.sectional_marks import sections_summary
from mppf.planning.sections import placement_text, press_sequence, split_plate
from plan_helpers import CylinderSurface, press  # noqa: F401 (fixture)

RADIUS_MM = 20000.0
LONG = Path(analytic.__file__).parent / "long"
T_MM = 20.0
TF_CYL_LOCAL = make_tf(np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]))
"""The plan_helpers cylinder (axis along u) turned so its axis runs along y, as cylinder_plate's."""


class TwistSurface:
    """z = a x y (the twisted plate in its own frame)."""

    def __init__(self, a):
        self.a = a

    def evaluate(self, u, v):
        return self.a * np.asarray(u, dtype=float) * np.asarray(v, dtype=float)

    def derivatives(self, u, v):
        u, v = np.asarray(u, dtype=float), np.asarray(v, dtype=float)
        zero = np.zeros_like(u)
        return self.a * u * v, self.a * v, self.a * u, zero, self.a + zero, zero


@pytest.fixture(scope="module")
def cylinder_job(press):
    design, flat = cylinder_plate(7500.0, 2400.0, RADIUS_MM)
    return plan_plate(design, flat, press, T_MM)


def _axes(press, active):
    gx, gy = np.meshgrid(press.punch_x_mm, press.punch_y_mm)
    return gx[active], gy[active]


def _exact_tips(press, section, surface, tf_world_local):
    """The ball contact of the exact design surface placed as the section places the design."""
    x, y = _axes(press, section.steps[-1].active)
    placed = PlacedSurface(surface, section.tf_press_design @ tf_world_local)
    up, lo = tip_heights(placed, x, y, tip_radius_mm=press.tip_radius_mm, thickness_mm=T_MM)
    return up.tip_mm, lo.tip_mm


def _recovered(press, section, tf_world_local, surface):
    """Per punch: height of the tips' mid point above the exact design, in the design's own frame."""
    final = section.steps[-1]
    x, y = _axes(press, final.active)
    mid = np.column_stack([x, y, 0.5 * (final.upper_mm[final.active] + final.lower_mm[final.active])])
    local = apply_tf(invert_tf(section.tf_press_design @ tf_world_local), mid)
    grid = np.full(press.shape, np.nan)
    grid[final.active] = local[:, 2] - surface.derivatives(local[:, 0], local[:, 1])[0]
    return grid


def _loaded_radius_mm(radius_mm):
    """The radius a cylinder of ``radius_mm`` is over-bent to (steel, ``T_MM``)."""
    from mppf.forming.springback import loaded_curvature
    from mppf.model.material import MATERIALS

    return 1.0 / float(loaded_curvature(np.array([1.0 / radius_mm]), T_MM, MATERIALS["steel"])[0])


def _held_on_cylinder(press, section, radius_mm):
    """Per punch (rows, cols): the tips' mid point as (arc length, y) on the cylinder of ``radius_mm`` tangent to the
    design at the plate's centre, and its height above that cylinder (NaN parked)."""
    final = section.steps[-1]
    x, y = _axes(press, final.active)
    mid = np.column_stack([x, y, 0.5 * (final.upper_mm[final.active] + final.lower_mm[final.active])])
    plate = apply_tf(invert_tf(section.tf_press_design @ hull_pose()), mid)
    where, height = np.full(press.shape + (2,), np.nan), np.full(press.shape, np.nan)
    where[final.active] = np.column_stack([radius_mm * np.arctan2(plate[:, 0], radius_mm - plate[:, 2]), plate[:, 1]])
    height[final.active] = radius_mm - np.hypot(plate[:, 0], radius_mm - plate[:, 2])
    return where, height


def _plate_keys(press, section):
    """(row, col) -> plate (x, y) rounded to mm, for the active punches of a section."""
    final = section.steps[-1]
    out = {}
    for r, c in zip(*np.nonzero(final.active)):
        key = (round(press.punch_x_mm[c] - section.plate_centre_mm[0]), round(press.punch_y_mm[r]
                                                                            - section.plate_centre_mm[1]))
        out[key] = (r, c)
    return out


def test_split_of_the_long_plate_covers_it_with_shared_strips(press):
    split = split_plate([7500.0, 2400.0], press)
    assert split.counts == (3, 2) and split.n_sections == 6
    assert np.all(np.mod(split.spacing_mm, [press.pitch_x_mm, press.pitch_y_mm]) == 0)
    bed = np.array(press.bed_size_mm)
    low = split.bed_centres_mm.min(axis=0) - bed / 2
    high = split.bed_centres_mm.max(axis=0) + bed / 2
    assert np.all(low <= [-3750.0, -1200.0]) and np.all(high >= [3750.0, 1200.0])
    assert np.all(split.transition_mm >= 3 * press.pitch_x_mm)
    # along x from -x to +x, across back and forth
    assert split.cells == [(0, 0), (0, 1), (1, 1), (1, 0), (2, 0), (2, 1)]
    assert np.all(np.diff(split.bed_centres_mm[:, 0]) >= 0)


def test_a_plate_that_fits_is_one_section(press):
    split = split_plate([3000.0, 2000.0], press)
    assert split.n_sections == 1 and split.cells == [(0, 0)]
    with pytest.raises(LimitError, match="too short"):
        split_plate([7500.0, 2000.0], press, transition_mm=3400.0)


def test_cylinder_sections_match_the_exact_contact_of_the_placed_design(press, cylinder_job):
    job = cylinder_job
    assert job.sections is not None and len(job.sections) == 6
    tf_world_local = hull_pose() @ TF_CYL_LOCAL
    for section in job.sections:
        up, lo = _exact_tips(press, section, CylinderSurface(RADIUS_MM), tf_world_local)
        final = section.steps[-1]
        assert np.abs(final.upper_mm[final.active] - up).max() < 0.2, section.index
        assert np.abs(final.lower_mm[final.active] - lo).max() < 0.2, section.index
        assert final.active.sum() >= 0.9 * press.rows * press.cols  # the section covers the bed


def test_cylinder_recovered_design_has_no_step_between_sections(press, cylinder_job):
    tf_world_local = hull_pose() @ TF_CYL_LOCAL
    surface = CylinderSurface(RADIUS_MM)
    sections = cylinder_job.sections
    recovered = [_recovered(press, s, tf_world_local, surface) for s in sections]
    compared = 0
    for k in range(len(sections)):
        keys_k = _plate_keys(press, sections[k])
        assert np.nanmax(np.abs(recovered[k])) < 2.0  # the tips hold the design itself (mid vs axis)
        for j in range(k):
            keys_j = _plate_keys(press, sections[j])
            shared = keys_k.keys() & keys_j.keys()
            steps = [abs(recovered[k][keys_k[p]] - recovered[j][keys_j[p]]) for p in shared]
            compared += len(steps)
            if steps:
                assert max(steps) < 0.2, (j + 1, k + 1)
    assert compared > 1000
    assert cylinder_job.sectional.max_border_step_mm < 0.2


def test_each_section_has_its_placement_and_marks(press, cylinder_job):
    job = cylinder_job
    for prev, section in zip([None] + job.sections[:-1], job.sections):
        (r1, c1), (r2, c2) = section.mark_punches
        assert np.allclose(section.marks_press_mm, [[press.punch_x_mm[c1], press.punch_y_mm[r1]],
                                                    [press.punch_x_mm[c2], press.punch_y_mm[r2]]])
        assert abs(section.marks_press_mm[1, 0] - section.marks_press_mm[0, 0]) >= 3000.0
        # the marks' material points (the exact development: flat (s, y) -> cylinder) lie over their punches
        # once the section is formed, as the section places the design
        s_mm, y_mm = section.marks_flat_mm[:, 0], section.marks_flat_mm[:, 1]
        material = np.column_stack([RADIUS_MM * np.sin(s_mm / RADIUS_MM), y_mm,
                                    RADIUS_MM * (1.0 - np.cos(s_mm / RADIUS_MM))])
        formed = apply_tf(section.tf_press_design @ hull_pose(), material)
        assert np.abs(formed[:, :2] - section.marks_press_mm).max() < 0.5
        # lying flat they are further apart: the draw-in of the bend, outward at both ends
        flat_xy = apply_tf(section.tf_press_flat, section.marks_flat_mm)[:, :2]
        draw_in = flat_xy[:, 0] - section.marks_press_mm[:, 0]
        assert draw_in[0] < -0.5 and draw_in[1] > 0.5 and np.abs(draw_in).max() < 5.0
        assert np.allclose(section.marks_plate_mm, apply_tf(
            section.tf_press_flat, section.marks_flat_mm)[:, :2] - section.plate_centre_mm, atol=1e-6)
        assert np.all(np.abs(section.marks_plate_mm) <= [3750.0, 1200.0])
        text = placement_text(section, prev)
        assert f"mark {section.index}a over punch row {r1 + 1}, col {c1 + 1}" in text
        assert f"lying flat the marks are {draw_in[0]:+.0f} / {draw_in[1]:+.0f} mm along x" in text
        if prev is not None:
            dx, dy = section.shift_from_mm(prev)
            assert f"{dx:+.0f} mm along x" in text and abs(dx) + abs(dy) > 0
    assert [s for s, _ in press_sequence(job)] == job.sections
    rows = sections_summary(job)
    assert [r["index"] for r in rows] == [1, 2, 3, 4, 5, 6] and all(r["n_steps"] >= 1 for r in rows)


def test_sectional_job_file_round_trip_and_versions(press, cylinder_job, tmp_path):
    doc = json.loads(cylinder_job.to_json())
    assert doc["version"] == JOB_VERSION == 5 and SECTIONS_VERSION == 3 and len(doc["sections"]) == 6
    back = job_from_dict(doc)
    assert back.to_json() == cylinder_job.to_json()
    assert [len(s.steps) for s in back.sections] == [len(s.steps) for s in cylinder_job.sections]
    assert np.allclose(back.sections[3].marks_flat_mm, cylinder_job.sections[3].marks_flat_mm)
    # the job's own steps are section 1's: older readers see a valid first section
    assert np.allclose(back.steps[-1].upper_mm, back.sections[0].steps[-1].upper_mm, equal_nan=True)
    bad = dict(doc, version=2)
    with pytest.raises(ConfigError, match="version-2 job cannot hold sections"):
        job_from_dict(bad)
    broken = json.loads(cylinder_job.to_json())
    del broken["sections"][1]["marks"]
    with pytest.raises(ConfigError, match="section 2.*lacks marks"):
        job_from_dict(broken)


def test_a_plate_that_fits_is_planned_in_one_piece(press):
    design, flat = cylinder_plate(3000.0, 2000.0, 8000.0, spacing_mm=100.0)
    one = plan_plate(design, flat, press, T_MM)
    assert one.sections is None and json.loads(one.to_json())["version"] == JOB_VERSION == 5
    assert one.to_json() == plan_job(design, flat, press, T_MM).to_json()
    long_design, long_flat = cylinder_plate(5000.0, 2000.0, 8000.0, spacing_mm=100.0)
    with pytest.raises(LimitError, match="does not fit on the bed"):
        place_flat(long_flat, press, T_MM)


def test_twisted_plate_in_sections_matches_its_exact_surface(press):
    length, width, twist = 7500.0, 2000.0, 60.0
    design, local = twisted_plate(length, width, twist, spacing_mm=100.0)
    flat = unfold(design).flat
    job = plan_sectional(design, flat, press, T_MM)
    assert job.sectional.to_doc()["counts"] == [3, 1]
    surface = TwistSurface(4.0 * twist / (length * width))
    for section in job.sections:
        up, lo = _exact_tips(press, section, surface, hull_pose())
        final = section.steps[-1]
        assert np.abs(final.upper_mm[final.active] - up).max() < 0.2
        assert np.abs(final.lower_mm[final.active] - lo).max() < 0.2
    assert job.sectional.max_border_step_mm < 0.2


@pytest.fixture(scope="module")
def springback_job(press):
    from mppf.model.material import MATERIALS

    design, flat = cylinder_plate(5000.0, 2000.0, RADIUS_MM, spacing_mm=150.0)
    return plan_plate(design, flat, press, T_MM, PlanOptions(springback=True, material=MATERIALS["steel"]))


def test_springback_corrections_blend_in_the_transition_zone(press, springback_job):
    first, second = springback_job.sections
    assert np.all(first.own_weight[first.steps[-1].active] == 1.0)
    weight = second.own_weight[second.steps[-1].active]
    assert weight.min() == 0.0 and weight.max() == 1.0 and np.any((weight > 0.05) & (weight < 0.95))
    # each section pressed the over-bend (far larger than the tips' reach of the design itself)
    tf_world_local = hull_pose() @ TF_CYL_LOCAL
    recovered = [_recovered(press, s, tf_world_local, CylinderSurface(RADIUS_MM)) for s in (first, second)]
    assert np.nanmax(np.abs(recovered[1])) > 20.0
    # where the second section's bed ends inside the first, the plate stays as the first left it: no step.
    # Compared at the same place of the plate (not punch by punch: on the over-bent plate, R 4.75 m, the punches
    # of two sections shifted by whole pitches meet it some 25 mm apart along the bend, where the over-bend
    # differs from the design by 0.3 x 25 mm), as heights above the plate's over-bent target
    keys = [_plate_keys(press, s) for s in (first, second)]
    edge_cols = {0, press.cols - 1}
    shared = [p for p in keys[1].keys() & keys[0].keys()
              if keys[1][p][1] in edge_cols or keys[1][p][0] in (0, press.rows - 1)]
    assert len(shared) >= 10
    loaded = _loaded_radius_mm(RADIUS_MM)
    held = [_held_on_cylinder(press, s, loaded) for s in (first, second)]
    border = np.array([keys[1][p] for p in shared])
    where = held[1][0][border[:, 0], border[:, 1]]
    there = LinearNDInterpolator(held[0][0][first.steps[-1].active], held[0][1][first.steps[-1].active])(where)
    steps = np.abs(held[1][1][border[:, 0], border[:, 1]] - there)
    assert np.isfinite(steps).sum() >= 10 and np.nanmax(steps) < 0.2
    assert springback_job.sectional.max_border_step_mm < 0.2


def test_one_section_as_a_single_piece_job(press, cylinder_job):
    from mppf.core.errors import InputError
    from mppf.planning.sections import section_job
    from mppf.planning.validate import validate_job

    third = section_job(cylinder_job, 3)
    assert third.sections is None and third.steps == cylinder_job.sections[2].steps
    assert np.array_equal(third.tf_press_design, cylinder_job.sections[2].tf_press_design)
    assert third.piece.index == 3 and third.piece.of == 6
    back = job_from_dict(json.loads(third.to_json()))
    assert back.layout.net_outline_mm.shape == cylinder_job.sections[2].layout.net_outline_mm.shape
    assert validate_job(back)["min_gap_mm"] >= T_MM - 0.01
    assert set(validate_job(cylinder_job)) >= {f"section {k}" for k in range(1, 7)}
    with pytest.raises(InputError, match="section 7 does not exist"):
        section_job(cylinder_job, 7)


def test_validators_check_every_section(press, cylinder_job):
    from mppf.planning.validate import check_job_document, validate_job

    doc = json.loads(cylinder_job.to_json())
    final = doc["sections"][1]["steps"][-1]
    r, c = next((r, c) for r, row in enumerate(final["active"]) for c, on in enumerate(row) if on)
    final["upper_mm"][r][c] = press.upper.max_mm + 50.0
    with pytest.raises(LimitError, match=r"^section 2: "):
        validate_job(job_from_dict(doc))
    final["upper_mm"][r][c] = "12.5"
    with pytest.raises(ConfigError, match=rf"section 2 step {len(doc['sections'][1]['steps'])} upper punch"):
        check_job_document(doc)


def test_corrections_per_section_blend_like_the_plan(press, cylinder_job):
    from mppf.planning.sectional import apply_section_corrections

    zero = [(np.zeros(press.shape), np.zeros(press.shape)) for _ in cylinder_job.sections]
    same = apply_section_corrections(cylinder_job, zero)
    for a, b in zip(same.sections, cylinder_job.sections):
        assert np.allclose(a.steps[-1].upper_mm, b.steps[-1].upper_mm, equal_nan=True)
    # one correction everywhere: every section takes it whole, transition zones included
    lift = [(np.full(press.shape, 2.0), np.full(press.shape, 2.0)) for _ in cylinder_job.sections]
    lifted = apply_section_corrections(cylinder_job, lift)
    for a, b in zip(lifted.sections, cylinder_job.sections):
        act = b.steps[-1].active
        assert np.allclose(a.steps[-1].upper_mm[act] - b.steps[-1].upper_mm[act], 2.0)
    # a correction of section 1 alone reaches the next section only where it overlaps section 1, by 1 - own_weight
    only_first = [lift[0]] + zero[1:]
    first = apply_section_corrections(cylinder_job, only_first)
    second, planned = first.sections[1], cylinder_job.sections[1]
    act = planned.steps[-1].active
    diff = second.steps[-1].upper_mm[act] - planned.steps[-1].upper_mm[act]
    assert np.allclose(diff, 2.0 * (1.0 - planned.own_weight[act]), atol=1e-9)
    assert first.sections[1].reports.validation.min_gap_mm >= T_MM - 0.01
    assert json.loads(first.to_json())["version"] == JOB_VERSION


def test_corrections_not_blended_are_each_sections_own(press, cylinder_job):
    """blend=False: every section presses its own correction at all its punches, transition zones included."""
    from mppf.planning.sectional import apply_section_corrections

    zero = [(np.zeros(press.shape), np.zeros(press.shape)) for _ in cylinder_job.sections]
    lift = (np.full(press.shape, 2.0), np.full(press.shape, 2.0))
    own = apply_section_corrections(cylinder_job, [lift] + zero[1:], blend=False)
    blended = apply_section_corrections(cylinder_job, [lift] + zero[1:])
    planned = cylinder_job.sections[1]
    act = planned.steps[-1].active
    assert np.any(planned.own_weight[act] < 1.0)  # section 2 overlaps section 1: the blend would reach it
    assert not np.allclose(blended.sections[1].steps[-1].upper_mm[act], planned.steps[-1].upper_mm[act])
    assert np.allclose(own.sections[1].steps[-1].upper_mm[act], planned.steps[-1].upper_mm[act])
    first = cylinder_job.sections[0].steps[-1]
    assert np.allclose(own.sections[0].steps[-1].upper_mm[first.active] - first.upper_mm[first.active], 2.0)


def test_sections_whose_over_bends_disagree_are_warned_of(press, springback_job):
    """Sections that step at their borders are warned of. A plate longer AND wider than the bed with springback
    (the 4.2 x 2.4 m cylinder in 2 x 2 sections) no longer steps: every section presses the whole plate's one
    over-bent target (it stepped by 128 mm when each section was over-bent about its own centre). The 9.4 m KCS
    stern plate still does: its curvature varies strongly over the plate and the target there is the principal
    arcs plus the design's departure from them, which the sections' fits follow only to some mm (docs/sections.md)."""
    from mppf.geometry.read import read_points
    from mppf.model.material import MATERIALS
    from mppf.planning.sectional import BORDER_STEP_LIMIT_MM, border_warnings

    assert springback_job.sectional.warnings == ()
    design, flat = cylinder_plate(4200.0, 2400.0, RADIUS_MM, spacing_mm=200.0)
    job = plan_plate(design, flat, press, T_MM, PlanOptions(springback=True, material=MATERIALS["steel"]))
    sectional = job.sectional.to_doc()
    assert sectional["counts"] == [2, 2] and sectional["max_border_step_mm"] < 0.2 and sectional["warnings"] == []
    kcs = read_points(LONG / "kcs_stern_bilge_9000x2400.csv").points
    job = plan_plate(kcs, unfold(kcs).flat, press, T_MM, PlanOptions(springback=True, material=MATERIALS["steel"]))
    sectional = job.sectional.to_doc()
    assert sectional["max_border_step_mm"] > BORDER_STEP_LIMIT_MM
    warned = sectional["warnings"]
    assert warned and all("step" in w and "--springback" in w for w in warned)
    assert len(warned) == sum(s.transition.border_step_mm > BORDER_STEP_LIMIT_MM for s in job.sections)
    assert border_warnings([0.0, 0.5], True) == [] and "kink" in border_warnings([0.0, 2.0], False)[0]
