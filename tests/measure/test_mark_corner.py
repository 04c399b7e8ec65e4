"""One reference mark: the corner of the plate as cut, the same in the job, the DXF, the placement, the request and compare."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mppf.core.polygon import distance_outside
from mppf.core.transform import apply_tf
from mppf.geometry.dxf import flat_drawing
from mppf.geometry.scans import read_header_mark
from mppf.geometry.unfold import unfold
from mppf.measure.mark import design_mark, mark_path, read_scan_mark, reference_mark
from mppf.model.job import job_from_dict
from mppf.model.job_parts import reference_corner_xy
from mppf.model.placement import placement_of


def test_the_mark_is_the_cut_corner_everywhere(planned_plate):
    design, _, _, job = planned_plate
    layout = job.layout
    assert layout.margin_mm > 0
    corner = layout.reference_corner_mm
    # the job: the corner of the outline as cut, outside the net outline by the margin (~141 mm from its corner)
    np.testing.assert_allclose(corner, reference_corner_xy(layout.outline_mm))
    assert distance_outside(layout.net_outline_mm, corner[None])[0] >= layout.margin_mm - 1e-6
    assert np.linalg.norm(corner - reference_corner_xy(layout.net_outline_mm)) > layout.margin_mm
    # the placement view: corner A is the mark
    placement = placement_of(layout)
    np.testing.assert_allclose(placement.cut_corners_mm[0], corner)
    np.testing.assert_allclose(placement.mark_mm, corner)
    # the cutter's DXF: its mark, laid on the press by the job, is the same corner of the same outline as cut;
    # the DXF draws the developed (flat) plate, the layout the plate seen from above once formed, so the two
    # positions differ by the development (1.5 mm on this weakly curved plate), not by the 141 mm to the net corner
    unfolded = unfold(design.points)
    drawing = flat_drawing(unfolded.flat, unfolded.faces, layout.margin_mm, tf_press_flat=job.tf_press_flat)
    on_press = apply_tf(job.tf_press_flat, np.r_[drawing.mark_mm, 0.0][None])[0, :2]
    assert np.linalg.norm(on_press - corner) < 5.0


def test_compare_takes_the_design_surface_at_the_cut_corner(planned_plate):
    design, _, _, job = planned_plate
    point = design_mark(design.points, job)
    on_press = apply_tf(job.tf_press_design, point[None])[0]
    # at the corner as cut, on the design surface extended past its edge (a smooth continuation: within mm
    # of the height of the nearest design points, which lie ~141 mm inward)
    np.testing.assert_allclose(on_press[:2], job.layout.reference_corner_mm, atol=1e-6)
    placed = apply_tf(job.tf_press_design, design.points)
    nearest = placed[np.argsort(np.linalg.norm(placed[:, :2] - on_press[:2], axis=1))[:5]]
    assert abs(on_press[2] - nearest[:, 2].mean()) < 40.0
    # a plate cut to its net outline: the mark is a design point; without a job, the design's own corner grown
    assert np.min(np.linalg.norm(design.points - design_mark(design.points, None), axis=1)) < 1e-6
    grown = design_mark(design.points, None, margin_mm=100.0)
    assert np.min(np.linalg.norm(design.points - grown, axis=1)) > 100.0


def test_an_older_job_that_stored_the_net_corner_is_read_with_the_cut_corner(planned_plate):
    job = planned_plate[3]
    doc = json.loads(job.to_json())
    doc["plate"]["reference_corner_mm"] = reference_corner_xy(job.layout.net_outline_mm).tolist()
    old = job_from_dict(doc)
    np.testing.assert_allclose(old.layout.reference_corner_mm, job.layout.reference_corner_mm)
    assert doc["version"] == 5  # a sealed job (this one as written before its seal)


@pytest.mark.parametrize("name, text", [
    ("scan.ply", "ply\nformat ascii 1.0\ncomment reference_mark_mm 1.5 -2 3e2\nelement vertex 1\nproperty float x\n"
                 "property float y\nproperty float z\nend_header\n0 0 0\n"),
    ("scan.xyz", "# from the scanner\n# reference_mark_mm: 1.5, -2, 300\n0 0 0\n"),
    ("scan.csv", "x,y,z\n#reference_mark_mm 1.5;-2;300\n0,0,0\n"),
])
def test_a_mark_in_the_scan_header(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    np.testing.assert_allclose(read_header_mark(path), [1.5, -2.0, 300.0])
    np.testing.assert_allclose(read_scan_mark(path), [1.5, -2.0, 300.0])
    # the mark file wins over the header
    mark_path(path).write_text(json.dumps({"reference_mark_mm": [4, 5, 6]}))
    np.testing.assert_allclose(read_scan_mark(path), [4.0, 5.0, 6.0])


def test_no_header_mark(tmp_path):
    after = tmp_path / "after.xyz"
    after.write_text("0 0 0\n# reference_mark_mm 1 2 3\n")  # after the first point: not the header
    ply_body = tmp_path / "body.ply"
    ply_body.write_text("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                        "property float z\nend_header\n0 0 0\ncomment reference_mark_mm 1 2 3\n")
    nan = tmp_path / "nan.xyz"
    nan.write_text("# reference_mark_mm nan 2 3\n0 0 0\n")
    other = tmp_path / "scan.e57"
    other.write_bytes(b"ASTM-E57 # reference_mark_mm 1 2 3\n")
    for path in (after, ply_body, nan, other, tmp_path / "missing.ply"):
        assert read_header_mark(path) is None, path
    assert reference_mark(after, np.zeros((3, 3)), None) is None
