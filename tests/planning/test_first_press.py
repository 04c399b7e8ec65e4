"""The first press under-bends by the declared yield-stress uncertainty (issue 40)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mppf.core.errors import InputError
from mppf.forming.material import DEFAULT_YIELD_UNCERTAINTY_PCT, check_yield_uncertainty, weakest_material
from mppf.forming.precompensate import predict_mid_heights
from mppf.forming.springback import loaded_curvature, unloaded_curvature
from mppf.loop.settings import LoopSettings
from mppf.model.material import Material
from mppf.model.plan_options import PlanOptions
from mppf.model.press import example_press_path, load_press
from mppf.planning.plan import plan_job
from plan_helpers import cylinder_points, developed_cylinder

T = 20.0
PRESS = dataclasses.replace(load_press(example_press_path()), margin_mm=0.0)
STEEL = Material(206000.0, 0.3, 235.0)
RADIUS_MM = 4000.0  # half the elastic-limit radius of 20 mm mild steel (8.3 m): springback matters


@pytest.fixture(scope="module")
def cylinder_plans():
    """The same cylinder planned for 0 % and 10 % declared yield scatter."""
    design = cylinder_points(RADIUS_MM, 2800.0, 1500.0)
    flat = developed_cylinder(RADIUS_MM, 2800.0, 1500.0)
    return {pct: plan_job(design, flat, PRESS, T,
                          PlanOptions(material=STEEL, springback=True, yield_uncertainty_pct=pct))
            for pct in (0.0, 10.0)}


def _sag_on(job, material) -> float:
    """Peak-to-peak mid height (mm) at the active punches the plate model predicts for ``material``."""
    final = job.steps[-1]
    act = final.active
    mid = predict_mid_heights(PRESS, final.upper_mm, final.lower_mm, act, job.layout.outline_mm, T, material)
    return float(np.ptp(mid[act]))


def test_weakest_material_lowers_only_the_yield_stress():
    weak = weakest_material(STEEL, 10.0)
    assert weak.yield_stress_mpa == pytest.approx(211.5)
    assert (weak.youngs_modulus_mpa, weak.poisson) == (STEEL.youngs_modulus_mpa, STEEL.poisson)
    assert weakest_material(STEEL, 0.0) is STEEL
    # the weaker plate springs back less: the same loaded bend leaves more curvature
    assert unloaded_curvature(1 / 2500.0, T, weak) > unloaded_curvature(1 / 2500.0, T, STEEL)


def test_plan_for_the_weakest_plate_records_what_it_assumed(cylinder_plans):
    for pct, job in cylinder_plans.items():
        first = job.reports.springback.first_press.to_doc()
        assert first["yield_uncertainty_pct"] == pct
        assert first["nominal_yield_mpa"] == 235.0
        assert first["planned_yield_mpa"] == pytest.approx(235.0 * (1 - pct / 100))
        assert job.layout.material == STEEL  # the correction's nominal material stays the nominal one
    # the over-bent arc is the one the springback law asks for the weakest plate: a larger loaded radius
    radii = {pct: min(abs(r) for r in job.reports.springback.loaded_radii_mm if r)
             for pct, job in cylinder_plans.items()}
    for pct, radius in radii.items():
        expected = 1.0 / float(loaded_curvature(1.0 / RADIUS_MM, T, weakest_material(STEEL, pct)))
        assert radius == pytest.approx(expected, rel=1e-3)
    assert radii[10.0] > radii[0.0] + 50.0


def test_ten_percent_plan_is_less_bent_by_what_the_springback_law_predicts(cylinder_plans):
    nominal_sag = {pct: _sag_on(job, STEEL) for pct, job in cylinder_plans.items()}
    # on the nominal plate the 10 % plan ends at the radius the law gives for the weak plate's loaded bend
    final_radius = 1.0 / float(unloaded_curvature(loaded_curvature(1.0 / RADIUS_MM, T, weakest_material(STEEL, 10.0)),
                                                  T, STEEL))
    assert final_radius == pytest.approx(4284.0, abs=5.0)  # 7 % flatter than the design's 4000 mm
    assert nominal_sag[10.0] / nominal_sag[0.0] == pytest.approx(RADIUS_MM / final_radius, rel=0.01)
    assert nominal_sag[10.0] < nominal_sag[0.0] - 2.0
    # the weakest plate of the range is the one the 10 % plan hits
    assert _sag_on(cylinder_plans[10.0], weakest_material(STEEL, 10.0)) == pytest.approx(nominal_sag[0.0], abs=0.5)
    # and the strokes themselves bend less
    sags = {pct: np.nanmax(job.steps[-1].upper_mm) - np.nanmin(job.steps[-1].upper_mm)
            for pct, job in cylinder_plans.items()}
    assert sags[10.0] < sags[0.0]


@pytest.mark.parametrize("pct", [-1.0, 50.0, 75.0, float("nan"), float("inf"), True, "10"])
def test_bad_uncertainty_is_refused_before_planning(pct):
    flat = developed_cylinder(1e9, 2400.0, 1600.0)
    with pytest.raises(InputError, match="yield-stress uncertainty") as info:
        plan_job(flat, flat, PRESS, T, PlanOptions(material=STEEL, springback=True, yield_uncertainty_pct=pct))
    assert "e.g. 10" in info.value.hint
    with pytest.raises(InputError, match="yield_uncertainty_pct"):
        LoopSettings(yield_uncertainty_pct=pct)


def test_uncertainty_without_springback_changes_nothing():
    flat = developed_cylinder(1e9, 2400.0, 1600.0)
    job = plan_job(flat, flat, PRESS, T, PlanOptions(yield_uncertainty_pct=10.0))
    assert job.reports.springback_doc() == {"enabled": False}


def test_the_loop_default_is_the_documented_one():
    assert LoopSettings().yield_uncertainty_pct == DEFAULT_YIELD_UNCERTAINTY_PCT
    assert LoopSettings.from_dict(LoopSettings(yield_uncertainty_pct=5).to_dict()).yield_uncertainty_pct == 5.0
    assert check_yield_uncertainty(0) == 0.0 and check_yield_uncertainty(49.9) == 49.9


def test_a_plate_planned_in_sections_is_under_bent_the_same_way():
    from mppf.examples.analytic import cylinder_plate
    from mppf.planning.sectional import plan_plate

    press = load_press(example_press_path())
    design, flat = cylinder_plate(4200.0, 2400.0, 6000.0, spacing_mm=100.0)
    jobs = {pct: plan_plate(design, flat, press, T,
                            PlanOptions(springback=True, material=STEEL, yield_uncertainty_pct=pct))
            for pct in (0.0, 10.0)}
    assert all(job.sections for job in jobs.values())  # larger than the bed
    radii = {}
    for pct, job in jobs.items():
        report = job.reports.springback_doc()
        assert report["first_press"]["planned_yield_mpa"] == pytest.approx(235.0 * (1 - pct / 100))
        assert all(section.layout.material == STEEL for section in job.sections)
        radii[pct] = min(abs(r) for r in report["loaded_radii_mm"] if r)
        expected = 1.0 / float(loaded_curvature(1.0 / 6000.0, T, weakest_material(STEEL, pct)))
        assert radii[pct] == pytest.approx(expected, rel=1e-3)
    assert radii[10.0] > radii[0.0] + 50.0
