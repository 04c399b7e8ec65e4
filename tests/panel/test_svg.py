"""The panel's drawings: colour scales, heat maps with punch names, legends."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import numpy as np

from mppf.panel.svg import (
    DIVERGING,
    NO_DATA,
    VIRIDIS,
    colour,
    heat_map,
    ink,
    legend,
    punch_name,
    scale_of,
    value_text,
)

SVG = "{http://www.w3.org/2000/svg}"


def test_colour_spans_the_map_clips_and_greys_nan():
    assert colour(0.0, 0.0, 10.0) == VIRIDIS[0]
    assert colour(10.0, 0.0, 10.0) == VIRIDIS[-1]
    assert colour(99.0, 0.0, 10.0) == VIRIDIS[-1]  # clipped
    assert colour(-5.0, -5.0, 5.0, DIVERGING) == DIVERGING[0]
    assert colour(0.0, -5.0, 5.0, DIVERGING) == DIVERGING[4]  # white at 0
    assert colour(float("nan"), 0.0, 1.0) == NO_DATA
    assert ink(VIRIDIS[0]) == "#fff" and ink(VIRIDIS[-1]) == "#000"


def test_scales_and_short_values():
    assert scale_of(np.array([[1.0, np.nan], [3.0, 2.0]])) == (1.0, 3.0)
    assert scale_of(np.array([[-4.0, 1.0]]), symmetric=True) == (-4.0, 4.0)
    assert scale_of(np.zeros((2, 2)), symmetric=True, at_least=2.5) == (-2.5, 2.5)
    lo, hi = scale_of(np.full((2, 2), 7.0), at_least=10.0)
    assert (lo, hi) == (2.0, 12.0)
    assert [value_text(v) for v in (3.14159, -12.345, 123.6, float("nan"))] == ["3.1", "-12.3", "124", "-"]


def test_punches_are_named_one_based_like_the_press():
    assert punch_name(0, 0) == "R1 C1"
    assert punch_name(2, 4) == "R3 C5"
    assert punch_name(2, 4, base=0) == "R2 C4"


def test_heat_map_draws_every_punch_row_one_at_the_bottom():
    values = np.arange(12, dtype=float).reshape(3, 4)
    values[1, 2] = np.nan
    flags = np.full((3, 4), "", dtype=object)
    flags[2, 3], flags[0, 0] = "faulted", "lagging"
    svg = heat_map(values, lo=0.0, hi=11.0, id_prefix="upper-actual", flags=flags, title="upper: actual")
    root = ET.fromstring(svg)
    cells = {r.get("id"): r for r in root.iter(f"{SVG}rect") if r.get("class") == "cell"}
    assert len(cells) == 12
    first, last = cells["upper-actual-r1-c1"], cells["upper-actual-r3-c4"]
    assert first.get("data-name") == "R1 C1" and first.get("data-mm") == "0.00"
    assert float(first.get("y")) > float(last.get("y"))  # row 1 drawn below row 3
    assert cells["upper-actual-r2-c3"].get("fill") == NO_DATA and cells["upper-actual-r2-c3"].get("data-mm") == ""
    texts = {t.get("id"): t.text for t in root.iter(f"{SVG}text") if t.get("id")}
    assert texts["upper-actual-v-r3-c4"] == "11.0" and texts["upper-actual-v-r2-c3"] == "-"
    marks = [r.get("class") for r in root.iter(f"{SVG}rect") if "flag" in (r.get("class") or "")]
    assert sorted(marks) == ["flag flag-faulted", "flag flag-lagging"]
    assert "upper: actual" in svg


def test_legend_names_its_ends():
    svg = legend(-2.5, 2.5, cmap=DIVERGING, label="deviation", id_prefix="dev")
    root = ET.fromstring(svg)
    texts = {t.get("id"): t.text for t in root.iter(f"{SVG}text") if t.get("id")}
    assert texts == {"dev-lo": "-2.5", "dev-hi": "2.5"}


def test_heat_map_escapes_its_title():
    svg = heat_map(np.zeros((1, 1)), lo=0, hi=1, title="<b>&")
    assert "<b>" not in svg and re.search(r"&lt;b&gt;&amp;", svg)
