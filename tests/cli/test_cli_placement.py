"""Where to lay the plate: the lines ``mppf press`` and ``mppf loop`` print before the press moves."""

import re

import numpy as np

from mppf.cli._placement import placement_lines
from mppf.model.job import Job
from mppf.model.job_parts import PlateLayout
from mppf.model.press import example_press_path, load_press


def _corners(lines):
    found = [re.search(r"corner ([A-Z]): x\s+(-?[\d.]+) mm, y\s+(-?[\d.]+) mm", line) for line in lines]
    return {m.group(1): (float(m.group(2)), float(m.group(3))) for m in found if m}


def test_the_corners_of_the_plate_as_cut_corner_a_nearest_the_mark(planned_plate):
    job = planned_plate[3]
    lines = placement_lines(job)
    corners = _corners(lines)
    cut = job.layout.outline_mm
    assert len(corners) >= 4
    # every corner printed is a vertex of the outline as cut (to the printed 0.1 mm)
    for x, y in corners.values():
        assert np.min(np.linalg.norm(cut - [x, y], axis=1)) < 0.06
    # corner A is the cut corner nearest the reference mark: the mark is on it (the plate as cut), and it
    # lies outside the net outline by the margin
    from mppf.core.polygon import distance_outside

    mark = job.layout.reference_corner_mm
    a = np.array(corners["A"])
    assert all(np.linalg.norm(a - mark) <= np.linalg.norm(np.array(c) - mark) for c in corners.values())
    assert np.linalg.norm(a - mark) < 0.06
    assert job.layout.margin_mm > 0
    assert distance_outside(job.layout.net_outline_mm, a[None])[0] >= job.layout.margin_mm - 0.1
    assert "nearest the reference mark" in next(line for line in lines if "corner A" in line)
    assert f"{job.layout.margin_mm:g} mm trim margin" in lines[0]


def test_a_plate_cut_to_its_net_outline_and_a_job_without_a_layout():
    press = load_press(example_press_path())
    square = np.array([[-500.0, -400.0], [500.0, -400.0], [500.0, 400.0], [-500.0, 400.0]])
    job = Job(press, 20.0, [], layout=PlateLayout(outline_mm=square, net_outline_mm=square))
    lines = placement_lines(job)
    assert "cut to its net outline" in lines[0]
    assert sorted(_corners(lines).values()) == sorted(map(tuple, square))
    assert "no plate outline" in placement_lines(Job(press, 20.0, []))[0]


def test_press_prints_where_to_lay_the_plate_before_it_moves(planned_plate, tmp_path, capsys):
    from mppf.cli import main
    from mppf.planning.job import save_job

    job = planned_plate[3]
    path = save_job(job, tmp_path / "job.json")
    assert main(["press", str(path), "--step", "1", "--time-scale", "200"]) == 0
    out = capsys.readouterr().out
    lines = placement_lines(job)
    # the corners come first, before the first step is pressed
    assert lines[1].strip() in out and out.index(lines[1].strip()) < out.index("step 1")
