"""The convergence chart of a plate's loop: measured cycles, tolerances, a y axis that holds them all."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import pytest

from mppf.panel.charts import convergence_svg

SVG = "{http://www.w3.org/2000/svg}"


def _points(svg: str) -> list[list[tuple[float, float]]]:
    root = ET.fromstring(svg)
    return [[tuple(map(float, xy.split(","))) for xy in line.get("points").split()]
            for line in root.iter(f"{SVG}polyline")]


def _y_labels(svg: str) -> list[float]:
    root = ET.fromstring(svg)
    return [float(t.text) for t in root.iter(f"{SVG}text") if t.get("text-anchor") == "end"
            and t.text and t.text.replace(".", "", 1).isdigit()]


def test_convergence_chart_plots_measured_cycles_and_tolerances():
    svg = convergence_svg([1, 2, 3], [8.0, 3.0, None], [3.0, 1.2, None], tolerance_mm=2.5, rms_tolerance_mm=1.0)
    root = ET.fromstring(svg)
    lines = _points(svg)
    assert len(lines) == 2 and all(len(p) == 2 for p in lines)  # cycle 3 is not measured yet
    assert len(list(root.iter(f"{SVG}circle"))) == 4
    assert "tolerance 2.5" in svg and "RMS tolerance 1" in svg
    # the largest deviation of cycle 1 is drawn higher than its RMS
    (x1, y1), (x2, y2) = lines[0][0], lines[1][0]
    assert x1 == x2 and y1 < y2


@pytest.mark.parametrize("values", [[None, None], [float("nan"), None]])
def test_convergence_chart_without_measurements_says_so(values):
    assert "no cycle measured yet" in convergence_svg([1, 2], values, values)


@pytest.mark.parametrize(("largest_mm", "top_mm"), [(8.0, 10.0), (2.0, 2.5), (40.0, 50.0), (0.15, 0.2)])
def test_the_y_axis_ends_at_a_round_value_above_every_point(largest_mm, top_mm):
    svg = convergence_svg([1, 2], [largest_mm, largest_mm / 2], [largest_mm / 4, largest_mm / 8])
    labels = _y_labels(svg)
    assert labels[0] == 0 and labels[-1] == pytest.approx(top_mm)
    assert len(labels) == 6  # five equal intervals


def test_a_tolerance_above_every_deviation_still_fits_on_the_chart():
    svg = convergence_svg([1], [0.8], [0.3], tolerance_mm=2.5, rms_tolerance_mm=1.0)
    assert _y_labels(svg)[-1] >= 2.5
    assert "tolerance 2.5" in svg
    # one measured cycle: a point each, no line
    assert _points(svg) == [] and len(list(ET.fromstring(svg).iter(f"{SVG}circle"))) == 2


def test_later_cycles_lie_to_the_right_and_smaller_deviations_lower():
    svg = convergence_svg([1, 2, 3, 4], [12.0, 6.0, 3.0, 1.5], [4.0, 2.0, 1.0, 0.5])
    for line in _points(svg):
        xs, ys = zip(*line)
        assert list(xs) == sorted(xs) and len(set(xs)) == 4
        assert list(ys) == sorted(ys)  # SVG y grows downwards: a falling deviation is a rising y
    cycle_labels = [t.text for t in ET.fromstring(svg).iter(f"{SVG}text") if t.get("text-anchor") == "middle"]
    assert ["1", "2", "3", "4"] == [c for c in cycle_labels if c.isdigit()]


def test_without_tolerances_no_dashed_line_is_drawn():
    svg = convergence_svg([1, 2], [5.0, 2.0], [1.5, 0.7])
    assert "stroke-dasharray" not in svg and "tolerance" not in svg
