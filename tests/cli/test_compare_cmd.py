"""``mppf compare``'s own helpers: the skin offset, the --mark option, the mark's reach, the terminal histogram."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.cli.compare_cmd import (
    HISTOGRAM_WIDTH,
    MARK_REACH_MM,
    ascii_histogram,
    check_mark_on_scan,
    parse_mark,
    skin_offset_mm,
)
from mppf.core.errors import InputError


@pytest.mark.parametrize(("skin", "offset_mm"), [("top", 10.0), ("mid", 0.0), ("bottom", -10.0)])
def test_the_skin_lies_half_the_thickness_from_the_mid_surface(skin, offset_mm):
    assert skin_offset_mm(skin, 20.0) == offset_mm


def test_a_skin_off_the_mid_surface_needs_a_positive_thickness():
    assert skin_offset_mm("mid", None) == 0.0
    with pytest.raises(InputError, match="--skin top needs the plate --thickness"):
        skin_offset_mm("top", None)
    with pytest.raises(InputError, match="--thickness"):
        skin_offset_mm("bottom", -20.0)


def test_a_mark_is_three_finite_numbers():
    assert parse_mark(None) is None
    np.testing.assert_array_equal(parse_mark("1204.5,-311,87.2"), [1204.5, -311.0, 87.2])
    for bad in ("1,2", "1,2,3,4", "1,two,3", "1,2,nan", "", "1;2;3"):
        with pytest.raises(InputError) as caught:
            parse_mark(bad)
        assert repr(bad) in str(caught.value) and "--mark 1204.5" in caught.value.hint


def test_a_mark_near_the_scan_is_taken_and_one_far_off_refused_with_the_scan_span():
    scan_mm = np.array([[0.0, 0.0, 0.0], [3000.0, 2000.0, 150.0]])
    check_mark_on_scan(np.array([3000.0 + MARK_REACH_MM - 1.0, 0.0, 0.0]), scan_mm, "scan.ply")  # a corner, a hole
    with pytest.raises(InputError) as caught:
        check_mark_on_scan(np.array([3000.0, 2000.0, 2150.0]), scan_mm, "scan.ply")  # 2000 mm above the top
    message = str(caught.value)
    assert "lies 2000 mm outside the scan scan.ply" in message and "0..3000, 0..2000, 0..150" in message
    with pytest.raises(InputError, match="^the mark 9000"):
        check_mark_on_scan(np.array([9000.0, 0.0, 0.0]), scan_mm, "scan.ply", what="the mark")


def test_the_histogram_has_a_line_per_bin_bars_to_scale_and_bins_beyond_the_tolerance_flagged():
    edges = np.array([-3.0, -1.0, 0.0, 1.0, 3.0])
    text = ascii_histogram(edges, [2, 100, 50, 0], tolerance_mm=2.5)
    title, *lines = text.splitlines()
    assert title == "deviation histogram (mm)" and len(lines) == 4
    assert lines[0].startswith("!") and lines[0].endswith(" 2")  # beyond 2.5 mm, with points
    assert lines[1].count("#") == HISTOGRAM_WIDTH and lines[2].count("#") == HISTOGRAM_WIDTH // 2
    assert lines[3].startswith(" ") and "#" not in lines[3]  # beyond, but empty: not flagged
    assert "." in ascii_histogram([0.0, 1.0, 2.0], [1, 10_000], tolerance_mm=2.5).splitlines()[1]  # few, not none
