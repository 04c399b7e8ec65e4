"""Which way round: a nearly symmetric plate is not judged without its mark; the mark, its file, the job."""

from __future__ import annotations

import json

import numpy as np
import pytest

import scan_helpers as sh
from mppf.core.errors import EXIT_PRESS
from mppf.core.transform import rotation_angle_deg
from mppf.measure.compare import compare
from mppf.measure.options import CompareOptions
from mppf.measure.mark import MARK_SUFFIX, design_mark, reference_mark
from mppf.model.job_parts import reference_corner_xy
from mppf.registration.scan_start import AmbiguousStart
from mppf.sim.scanner import SimulatedScanner


def _symmetric_case(seed=4):
    formed = sh.form(8000.0, 18000.0, asymmetric=False)
    design = formed.mid_surface_points(50.0)
    corner = reference_corner_xy(formed.outline_xy_mm)
    sample = SimulatedScanner(seed=seed).sample(formed, corner)
    mark = design[np.argmin(np.linalg.norm(design[:, :2] - corner, axis=1))]
    return design, sample, mark


def test_a_symmetric_plate_without_a_mark_is_not_judged():
    design, sample, _ = _symmetric_case()
    with pytest.raises(AmbiguousStart, match="ambiguous: give the reference mark") as caught:
        compare(design, sample.points, CompareOptions(offset_mm=sh.THICKNESS_MM / 2))
    assert caught.value.exit_code == EXIT_PRESS == 4
    pair = caught.value.candidates
    assert len(pair) == 2 and pair[0]["name"] != pair[1]["name"]
    assert pair[1]["turn_deg"] > 170.0  # the half turn
    assert all(np.isfinite(c["residual_mm"]) for c in pair)
    assert "residual" in str(caught.value) and "turned 180 deg" in str(caught.value)


def test_the_mark_settles_it_and_ambiguous_start_tells_the_truth():
    design, sample, mark = _symmetric_case()
    c = compare(design, sample.points, CompareOptions(offset_mm=sh.THICKNESS_MM / 2,
            reference_mark=(sample.mark_mm, mark)))
    assert rotation_angle_deg(c.transform @ sample.tf_scan_press) < 10.0
    assert c.registration.ambiguous_start  # the geometry alone could not tell
    assert c.registration.init["settled_by"] in ("mark", "held mark")
    assert c.to_dict()["registration"]["ambiguous_start"] is True


def test_an_asymmetric_plate_is_not_flagged():
    _, _, c = sh.bump_result()
    assert not c.registration.ambiguous_start
    assert c.registration.init["settled_by"] == "fit"


def test_the_mark_file_beside_the_scan_and_the_design_corner(tmp_path):
    design, sample, mark = _symmetric_case()
    scan = tmp_path / "scan.ply"
    assert reference_mark(scan, design, None) is None  # no file, no mark
    (tmp_path / f"scan.ply{MARK_SUFFIX}").write_text(json.dumps({"reference_mark_mm": sample.mark_mm.tolist()}))
    measured, on_design = reference_mark(scan, design, None)
    assert np.allclose(measured, sample.mark_mm)
    assert np.allclose(on_design, design_mark(design, None))
    # given on the command line, it wins over the file
    measured, _ = reference_mark(scan, design, None, mark_mm=[1.0, 2.0, 3.0])
    assert np.allclose(measured, [1.0, 2.0, 3.0])


def test_a_scan_registered_from_a_known_start_keeps_its_turn_and_skips_the_choice():
    """A union of rescans in the frame of a compared scan (the loop's): registered from that scan's transform, the
    symmetric plate is judged without its mark, in the same pose; a malformed start is refused."""
    from mppf.core.errors import InputError

    design, sample, mark = _symmetric_case()
    first = compare(design, sample.points, CompareOptions(offset_mm=sh.THICKNESS_MM / 2,
            reference_mark=(sample.mark_mm, mark)))
    again = compare(design, sample.points, CompareOptions(offset_mm=sh.THICKNESS_MM / 2, start_from=first))
    assert "shares its frame" in again.notes[0] and "settled there by the reference mark" in again.notes[0]
    init = again.registration.init
    assert init["settled_by"] == "earlier scan" and init["first_settled_by"] in ("mark", "held mark")
    # a union of three starts from the union of two: how the first scan was settled is kept
    third = compare(design, sample.points, CompareOptions(offset_mm=sh.THICKNESS_MM / 2, start_from=again))
    assert third.registration.init["first_settled_by"] == init["first_settled_by"]
    from_tf = compare(design, sample.points, CompareOptions(offset_mm=sh.THICKNESS_MM / 2, start_from=first.transform))
    np.testing.assert_allclose(from_tf.transform, again.transform, atol=1e-9)
    assert rotation_angle_deg(again.transform @ np.linalg.inv(first.transform)) < 0.05
    assert np.linalg.norm(again.transform[:3, 3] - first.transform[:3, 3]) < 1.0
    assert again.verdict.kind == first.verdict.kind
    assert again.rms_mm == pytest.approx(first.rms_mm, abs=0.02)
    with pytest.raises(InputError, match="start_from"):
        compare(design, sample.points, CompareOptions(start_from=np.eye(3)))
