"""Deviation pictures of a comparison: the colour map, the histogram, the punch map (mppf.report.deviation)."""

from __future__ import annotations

import numpy as np
import pytest

import scan_helpers as sh
from mppf.report.deviation import deviation_map_figure, histogram_figure, plot_deviation, punch_map_figure


def test_deviation_map_is_written_as_png(tmp_path):
    _, _, c = sh.bump_result()
    path = plot_deviation(c, tmp_path / "map.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    fig = deviation_map_figure(c, title="K9")
    assert fig.axes[0].get_title() == "K9"
    assert len(fig.axes) == 2  # the map and its colour bar


def test_histogram_has_one_bar_per_bin_coloured_by_the_tolerance():
    _, _, c = sh.bump_result()
    ax = histogram_figure(c).axes[0]
    assert len(ax.patches) == len(c.histogram_counts) + 1  # the bars and the tolerance band
    heights = [p.get_height() for p in ax.patches[:len(c.histogram_counts)]]
    assert heights == pytest.approx(c.histogram_counts.tolist())


def test_punch_map_circles_the_interpolated_punches():
    _, _, c = sh.formed_and_scan()
    press = sh.press()
    ax = punch_map_figure(c, press.punch_x_mm, press.punch_y_mm).axes[0]
    circles = [line for line in ax.lines if line.get_marker() == "o"]
    assert len(circles) == 1 and len(circles[0].get_xdata()) == int(c.punch_interpolated.sum())
    assert np.isfinite(c.punch_deviation_mm).any()
