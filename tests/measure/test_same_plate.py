"""A badly formed plate is not a wrong plate (issue 20.5, mppf.measure.same_plate): judged, not refused."""

from __future__ import annotations

import numpy as np
import pytest

import scan_helpers as sh
from mppf.core.errors import GeometryError
from mppf.model.material import Material
from mppf.measure.compare import compare
from mppf.measure.options import CompareOptions
from mppf.measure.same_plate import Evidence
from mppf.sim.forming import PlateSample, form_plate
from mppf.sim.scanner import SimulatedScanner


def _compare(formed, seed=2, **options):
    design = sh.form(4000.0, 9000.0).mid_surface_points(50.0)
    sample = SimulatedScanner(seed=seed).sample(formed)
    return compare(design, sample.points, CompareOptions(offset_mm=sh.THICKNESS_MM / 2, tf_press_design=np.eye(4),
                   punch_xy_mm=sh.punch_grid(), rotation_hint=np.linalg.inv(sample.tf_scan_press), **options))


def test_this_plate_formed_twice_too_curved_is_out_of_tolerance_not_refused():
    c = _compare(sh.form(2000.0, 4500.0))  # the same cut plate, bent twice as much: RMS about 75 mm
    assert c.rms_mm > 30.0
    assert c.verdict.kind == "out_of_tolerance" and c.verdict.badly_formed
    assert c.headline.startswith("OUT of tolerance: badly formed: only")
    assert c.plate_evidence.same_plate and c.plate_evidence.correlation > 0.9 and c.plate_evidence.outline_matches
    doc = c.to_dict()
    assert doc["badly_formed"]["same_plate"] and doc["verdict"]["badly_formed"]
    assert any(note.startswith("badly formed") for note in c.notes)
    assert np.isfinite(c.punch_deviation_mm).sum() > 100  # the deviation map and the punches are there


def test_a_plate_near_its_design_is_not_badly_formed():
    c = _compare(sh.form(4000.0, 9000.0))
    assert c.plate_evidence is None and not c.verdict.badly_formed and c.to_dict()["badly_formed"] is None


def test_a_smaller_plate_far_from_the_design_is_another_plate():
    p = sh.press()
    px, py = np.meshgrid(p.punch_x_mm, p.punch_y_mm)
    mid = px**2 / 3000.0 - py**2 / 9000.0
    active = (np.abs(px) <= 1300) & (np.abs(py) <= 900)
    outline = [[-1200.0, -800.0], [1200.0, -800.0], [1200.0, 800.0], [-1200.0, 800.0]]
    other = form_plate(p, mid + 10.0, mid - 10.0, active, PlateSample(20.0, Material()), outline)
    with pytest.raises(GeometryError, match="does not match the design: only .* outline is .* another plate"):
        _compare(other)


def test_a_scan_in_other_units_is_still_refused():
    design = sh.design()
    with pytest.raises(GeometryError, match="units"):
        compare(design, design / 1000.0)
    with pytest.raises(GeometryError, match="units"):
        compare(design, design * 25.4)


def test_the_evidence_rule():
    near = Evidence(30.0, 25.0, (2990.0, 1990.0), (3000.0, 2000.0), 0.9, 12000)
    assert near.same_plate
    assert not Evidence(30.0, 25.0, (2400.0, 1990.0), (3000.0, 2000.0), 0.9, 12000).same_plate  # outline
    assert not Evidence(30.0, 25.0, (2990.0, 1990.0), (3000.0, 2000.0), 0.1, 12000).same_plate  # shape
    assert Evidence(30.0, 25.0, (2990.0, 1990.0), (3000.0, 2000.0), None, 12000).same_plate  # flat: outline decides
    assert not Evidence(30.0, 25.0, (2990.0, 1990.0), (3000.0, 2000.0), 0.9, 12000, 40000).same_plate  # count
    assert Evidence(30.0, 25.0, (2990.0, 1990.0), (3000.0, 2000.0), 0.9, 12000, 15000).same_plate
    assert "12000 points against 15000 expected" in Evidence(30.0, 25.0, (2990.0, 1990.0), (3000.0, 2000.0), 0.9,
                                                             12000, 15000).describe()
