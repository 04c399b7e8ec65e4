"""Stroke planning end to end on closed-form plates and the real hull patches."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mppf.core.errors import GeometryError, InputError, LimitError
from mppf.geometry.read import read_points
from mppf.model.material import Material
from mppf.model.plan_options import PlanOptions
from mppf.model.press import example_press_path, load_press, press_from_dict
from mppf.planning.job import load_job, save_job
from mppf.planning.plan import plan_job, plan_summary
from mppf.forming.precompensate import predict_mid_heights
from mppf.forming.springback import loaded_curvature
from mppf.core.transform import apply_rotation, apply_tf
from mppf.geometry.unfold import unfold
from plan_helpers import cylinder_points, cylinder_tips_mm, developed_cylinder

T = 20.0
EXAMPLE_PRESS = load_press(example_press_path())
PRESS = dataclasses.replace(EXAMPLE_PRESS, margin_mm=0.0)  # exact geometry: the plate cut to its net outline


def _press(**changes) -> object:
    doc = PRESS.to_dict()
    for key, value in changes.items():
        table, name = key.split("__")
        doc[table][name] = value
    return press_from_dict(doc)


def _expected_cylinder_tips(job, radius_mm):
    """Closed-form tips of a valley cylinder whose axis the plan put along press x."""
    axis_dir = apply_rotation(job.tf_press_design, [[1.0, 0.0, 0.0]])[0]
    assert abs(abs(axis_dir[0]) - 1.0) < 1e-9  # the cylinder axis lies along the matrix
    axis_point = apply_tf(job.tf_press_design, [[0.0, 0.0, radius_mm]])[0]
    gy = np.broadcast_to(job.punch_y_mm[:, None], job.press.shape) - axis_point[1]
    lowest = apply_tf(job.tf_press_design, [[0.0, 0.0, 0.0]])[0]
    if axis_point[2] > lowest[2]:  # a valley
        up, lo = cylinder_tips_mm(gy, radius_mm, job.press.tip_radius_mm, job.thickness_mm)
        return up + lowest[2], lo + lowest[2]
    # a ridge (the registration may turn the plate over): mirror the valley about z = 0
    up, lo = cylinder_tips_mm(gy, radius_mm, job.press.tip_radius_mm, job.thickness_mm)
    return -lo + lowest[2], -up + lowest[2]


@pytest.fixture(scope="module")
def cylinder_job():
    radius = 3000.0
    design = cylinder_points(radius, 2800.0, 1500.0)
    flat = developed_cylinder(radius, 2800.0, 1500.0)
    return plan_job(design, flat, PRESS, T), radius


def test_cylinder_matches_ball_on_offset_cylinder(cylinder_job):
    job, radius = cylinder_job
    final = job.steps[-1]
    act = final.active
    exp_up, exp_lo = _expected_cylinder_tips(job, radius)
    assert act.sum() > 100
    np.testing.assert_allclose(final.upper_mm[act], exp_up[act], atol=0.01)
    np.testing.assert_allclose(final.lower_mm[act], exp_lo[act], atol=0.01)
    assert np.isnan(final.upper_mm[~act]).all() and np.isnan(final.lower_mm[~act]).all()


def test_symmetric_plate_gives_symmetric_strokes(cylinder_job):
    job, _ = cylinder_job
    final = job.steps[-1]
    for grid in (final.upper_mm, final.lower_mm):
        np.testing.assert_allclose(grid, grid[::-1, :], atol=0.01, equal_nan=True)
        np.testing.assert_allclose(grid, grid[:, ::-1], atol=0.01, equal_nan=True)
    np.testing.assert_array_equal(final.active, final.active[::-1, ::-1])


def test_travel_is_minimal_and_centred(cylinder_job):
    job, _ = cylinder_job
    final = job.steps[-1]
    act = final.active
    travel = np.concatenate([final.upper_mm[act] - T, final.lower_mm[act]])
    # minimax: the largest upward and downward travel are equal
    assert travel.max() == pytest.approx(-travel.min(), abs=1e-6)
    assert job.reports.pose.max_travel_mm == pytest.approx(np.abs(travel).max(), abs=1e-6)


def test_flat_plate_gives_flat_strokes():
    flat = developed_cylinder(1e9, 2400.0, 1600.0)
    job = plan_job(flat, flat, PRESS, T)
    final = job.steps[-1]
    act = final.active
    assert len(job.steps) == 1
    np.testing.assert_allclose(final.upper_mm[act], T, atol=1e-6)
    np.testing.assert_allclose(final.lower_mm[act], 0.0, atol=1e-6)
    # the flat lies centred on the bed, bottom skin at z = 0
    corners = np.array(job.reports.plate_corners_mm)
    np.testing.assert_allclose(np.abs(corners[:, :2]), [[1200.0, 800.0]] * 4, atol=1e-6)
    np.testing.assert_allclose(corners[:, 2], 0.0)


def test_dome_from_unfold_is_symmetric_and_within_gap():
    u, v = np.meshgrid(np.linspace(-1300, 1300, 27), np.linspace(-900, 900, 19), indexing="ij")
    design = np.column_stack([u.ravel(), v.ravel(), (u**2 / 16000.0 + v**2 / 12000.0).ravel()])
    job = plan_job(design, unfold(design).flat, PRESS, T)
    final = job.steps[-1]
    for grid in (final.upper_mm, final.lower_mm):
        np.testing.assert_allclose(grid, grid[::-1, ::-1], atol=0.02, equal_nan=True)
    gap = (final.upper_mm - final.lower_mm)[final.active]
    assert gap.min() >= T - 0.01


def test_multi_step_is_monotonic_and_ends_at_target(cylinder_job):
    job1, _ = cylinder_job
    flat = developed_cylinder(3000.0, 2800.0, 1500.0)
    job = plan_job(cylinder_points(3000.0, 2800.0, 1500.0), flat, PRESS, T, PlanOptions(steps=4))
    assert len(job.steps) == 4 and job.reports.n_steps == 4
    act = job.steps[-1].active
    np.testing.assert_allclose(job.steps[-1].upper_mm[act], job1.steps[-1].upper_mm[act], atol=1e-9)
    ups = np.array([s.upper_mm[act] for s in job.steps])
    moves = np.diff(np.vstack([np.full(act.sum(), T), ups]), axis=0)
    assert np.all(moves * np.sign(moves[-1]) >= -1e-9)
    np.testing.assert_allclose(moves, np.broadcast_to(moves[0], moves.shape), atol=1e-6)  # equal fractions


def test_step_count_follows_the_dimpling_limit():
    design = cylinder_points(2000.0, 2800.0, 1500.0)
    flat = developed_cylinder(2000.0, 2800.0, 1500.0)
    strict = _press(forming__max_neighbour_diff_mm=5.0)
    job = plan_job(design, flat, strict, T)
    n = len(job.steps)
    assert n > 1
    assert job.reports.validation.max_neighbour_step_mm <= 5.0 + 1e-6
    # one step fewer would exceed the limit: the validation refuses it
    with pytest.raises(LimitError, match="dimpling limit"):
        plan_job(design, flat, strict, T, PlanOptions(steps=n - 1))


def test_springback_over_bends_a_cylinder_then_refines_on_the_plate_model():
    radius = 4000.0
    design = cylinder_points(radius, 2800.0, 1500.0)
    flat = developed_cylinder(radius, 2800.0, 1500.0)
    steel = Material(206000.0, 0.3, 235.0)
    job = plan_job(design, flat, PRESS, T, PlanOptions(material=steel, springback=True))
    loaded_radius = 1.0 / float(loaded_curvature(1.0 / radius, T, steel))
    assert loaded_radius < radius
    report = job.reports.springback_doc()
    assert report["enabled"]
    # the first guess: the principal arc over-bent to the loaded radius
    assert min(abs(r) for r in report["loaded_radii_mm"] if r) == pytest.approx(loaded_radius, rel=1e-3)
    # then virtual cycles on the plate model bring its predicted shape onto the design
    refinement = report["refinement"]
    assert refinement["virtual_cycles"] >= 1
    assert refinement["history_mm"][0] > 1.0 > 0.2 > refinement["predicted_max_mm"]
    final = job.steps[-1]
    act = final.active
    predicted = predict_mid_heights(PRESS, final.upper_mm, final.lower_mm, act, job.layout.outline_mm, T,
                                    steel)
    axis_point = apply_tf(job.tf_press_design, [[0.0, 0.0, 0.0]])[0]
    gy = np.broadcast_to(job.punch_y_mm[:, None], job.press.shape) - axis_point[1]
    up, lo = cylinder_tips_mm(gy, radius, PRESS.tip_radius_mm, T, lift_mm=axis_point[2])
    target = 0.5 * (up + lo)
    error = (predicted - target)[act]
    assert np.ptp(error) < 2 * refinement["predicted_max_mm"] + 1e-6  # up to a rigid offset
    # the strokes still over-bend: the pressed cylinder is sharper than the design
    sag = 0.5 * (final.upper_mm + final.lower_mm)
    assert np.nanmax(sag[act]) - np.nanmin(sag[act]) > np.max(target[act]) - np.min(target[act]) + 5.0


def test_trim_margin_adds_the_punches_under_the_excess_band():
    radius = 3000.0
    design = cylinder_points(radius, 2800.0, 1500.0)
    flat = developed_cylinder(radius, 2800.0, 1500.0)
    net = plan_job(design, flat, PRESS, T)
    grown = plan_job(design, flat, PRESS, T, PlanOptions(margin_mm=100.0))
    assert net.layout.margin_mm == 0.0 and grown.layout.margin_mm == 100.0
    assert grown.reports.n_active > net.reports.n_active
    assert np.all(grown.steps[-1].active[net.steps[-1].active])  # the net punches stay
    outline = np.asarray(grown.layout.outline_mm)
    net_outline = np.asarray(grown.layout.net_outline_mm)
    assert np.ptp(outline, axis=0) == pytest.approx(np.ptp(net_outline, axis=0) + 200.0, abs=1.0)
    # the press's default margin applies when none is given
    assert plan_job(design, flat, EXAMPLE_PRESS, T).layout.margin_mm == EXAMPLE_PRESS.margin_mm


@pytest.mark.parametrize("margin", [-1.0, float("nan"), 1e4, True])
def test_bad_trim_margin(margin):
    flat = developed_cylinder(1e9, 2400.0, 1600.0)
    with pytest.raises(InputError, match="trim margin"):
        plan_job(flat, flat, PRESS, T, PlanOptions(margin_mm=margin))


def test_springback_needs_material():
    flat = developed_cylinder(1e9, 2400.0, 1600.0)
    with pytest.raises(InputError, match="material"):
        plan_job(flat, flat, PRESS, T, PlanOptions(springback=True))


@pytest.mark.parametrize("thickness", [0.0, -5.0, float("nan")])
def test_bad_thickness(thickness):
    flat = developed_cylinder(1e9, 2400.0, 1600.0)
    with pytest.raises(InputError, match="thickness"):
        plan_job(flat, flat, PRESS, thickness)


def test_plate_larger_than_bed():
    flat = developed_cylinder(1e9, 3600.0, 1600.0)
    with pytest.raises(LimitError, match="does not fit"):
        plan_job(flat, flat, PRESS, T)


def test_strokes_beyond_limits_name_the_punches():
    design = cylinder_points(2000.0, 2800.0, 1500.0)
    flat = developed_cylinder(2000.0, 2800.0, 1500.0)
    tight = _press(upper__min_mm=-20.0, upper__park_mm=40.0, upper__max_mm=40.0, lower__max_mm=20.0,
                   lower__min_mm=-40.0, lower__park_mm=-40.0)
    with pytest.raises(LimitError, match=r"beyond the press limits.*(upper|lower)\[\d+,\d+\]"):
        plan_job(design, flat, tight, T)


def test_flat_of_another_plate_is_refused(hull_dir):
    k1 = read_points(hull_dir / "K1_midbody_bilge.csv").points
    p2 = read_points(hull_dir / "P2_bow_flare_smooth.csv").points
    with pytest.raises(GeometryError, match="does not belong"):
        plan_job(k1, unfold(p2).flat, PRESS, T)
    # unpaired (different point count): judged by area
    other = developed_cylinder(1e9, 2000.0, 1200.0)
    with pytest.raises(GeometryError, match="does not belong"):
        plan_job(k1, other, PRESS, T)


def test_unpaired_flat_uses_icp():
    radius = 3000.0
    design = cylinder_points(radius, 2800.0, 1500.0)
    flat = developed_cylinder(radius, 2800.0, 1500.0, n_u=37, n_v=27)
    job = plan_job(design, flat, PRESS, T)
    assert job.reports.registration.method == "point"
    exp_up, _ = _expected_cylinder_tips(job, radius)
    act = job.steps[-1].active
    np.testing.assert_allclose(job.steps[-1].upper_mm[act], exp_up[act], atol=0.01)


def test_job_round_trip(tmp_path, cylinder_job):
    job, _ = cylinder_job
    path = save_job(job, tmp_path / "job.json")
    back = load_job(path)
    assert len(back.steps) == len(job.steps)
    for a, b in zip(back.steps, job.steps):
        np.testing.assert_array_equal(a.active, b.active)
        np.testing.assert_allclose(a.upper_mm, b.upper_mm, atol=1e-4, equal_nan=True)
        np.testing.assert_allclose(a.lower_mm, b.lower_mm, atol=1e-4, equal_nan=True)
    np.testing.assert_allclose(back.tf_press_design, job.tf_press_design)
    for name in ("registration", "validation", "plate_corners_mm", "inputs", "springback", "n_steps", "pose"):
        assert getattr(back.reports, name) is not None
    assert back.reports.to_doc() == job.reports.to_doc()
    assert plan_summary(back)["n_steps"] == len(job.steps)


HULL = ["K1_midbody_bilge.csv", "K2_fwd_bilge_convex.csv", "K3_stern_saddle.csv", "P1_midbody_bilge.csv",
        "P1_midbody_bilge_smooth.csv", "P2_bow_flare.csv", "P2_bow_flare_smooth.csv", "P3_stern_saddle.csv",
        "P3_stern_saddle_smooth.csv"]


@pytest.mark.parametrize("name", HULL)
def test_hull_patch_plans_within_the_example_press(hull_dir, name):
    design = read_points(hull_dir / name).points
    job = plan_job(design, unfold(design).flat, PRESS, T)
    validation = job.reports.validation.to_doc()
    assert validation["passed"]
    for step in job.steps:
        act = step.active
        assert act.sum() >= 200
        assert PRESS.upper.min_mm <= step.upper_mm[act].min() and step.upper_mm[act].max() <= PRESS.upper.max_mm
        assert PRESS.lower.min_mm <= step.lower_mm[act].min() and step.lower_mm[act].max() <= PRESS.lower.max_mm
        assert (step.upper_mm - step.lower_mm)[act].min() >= T - 0.01
    assert job.reports.validation.contact_exact_fraction == 1.0
    assert job.reports.registration.neighbour_strain_p95_pct < 0.5


def test_edge_contacts_use_the_trim_allowance():
    # plate edge 15 mm outside the outermost punch rows: the upper balls there touch
    # the (extended) surface past the edge
    design = cylinder_points(2000.0, 2800.0, 1380.0)
    flat = developed_cylinder(2000.0, 2800.0, 1380.0)
    job = plan_job(design, flat, PRESS, T)
    beyond = job.reports.validation.contact_beyond_edge_mm
    assert 1.0 < beyond < PRESS.trim_allowance_mm
    with pytest.raises(GeometryError, match="past the plate edge"):
        plan_job(design, flat, _press(forming__trim_allowance_mm=beyond / 2), T)
