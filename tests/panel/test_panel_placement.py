"""Where to lay the plate, drawn (``mppf/panel/placement.py``): the bed, the punches, the plate and its corners."""

from __future__ import annotations

import xml.etree.ElementTree as ET

from panel_helpers import layout_job

from mppf.model.placement import placement_of
from mppf.panel.placement import bed_svg

SVG = "{http://www.w3.org/2000/svg}"


def test_bed_drawing_shows_every_punch_the_outlines_and_the_corners():
    job = layout_job()
    svg = bed_svg(job.press, placement_of(job.layout), active=job.steps[0].active)
    root = ET.fromstring(svg)
    punches = [c for c in root.iter(f"{SVG}circle") if c.get("r") == f"{job.press.tip_radius_mm:.0f}"]
    assert len(punches) == job.press.rows * job.press.cols
    assert sum(c.get("fill") != "#ffffff" for c in punches) == int(job.steps[0].active.sum())
    assert len([p for p in root.iter(f"{SVG}polygon") if p.get("class") == "cut-outline"]) == 1
    assert len([p for p in root.iter(f"{SVG}polygon") if p.get("class") == "net-outline"]) == 1
    labels = {t.get("data-corner"): "".join(t.itertext()) for t in root.iter(f"{SVG}text") if t.get("data-corner")}
    assert labels == {"A": "A -1200, -800", "B": "B 1300, -800", "C": "C 1300, 700", "D": "D -1200, 700"}
    # press y is up: the drawing flips it, row 1 at the bottom
    r1 = [t for t in root.iter(f"{SVG}text") if t.text == "R1"][0]
    r16 = [t for t in root.iter(f"{SVG}text") if t.text == "R16"][0]
    assert float(r1.get("y")) > float(r16.get("y"))


def test_bed_alone():
    job = layout_job()
    root = ET.fromstring(bed_svg(job.press, None))
    assert not list(root.iter(f"{SVG}polygon"))
