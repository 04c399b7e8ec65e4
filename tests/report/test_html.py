"""The HTML report of a comparison: one self-contained page (mppf.report.html)."""

from __future__ import annotations

import numpy as np

import scan_helpers as sh
from mppf.report.html import comparison_report, statistics_rows, table_html


def test_report_of_a_plate_out_of_tolerance_with_its_punches():
    _, _, c = sh.formed_and_scan()
    press = sh.press()
    page = comparison_report(c, design_name="design <a&b>.csv", measured_name="scan.ply",
                             punch_x_mm=press.punch_x_mm, punch_y_mm=press.punch_y_mm, extra_rows=[("plate", "K9")])
    assert page.startswith("<!DOCTYPE html>") and page.rstrip().endswith("</html>")
    assert "design &lt;a&amp;b&gt;.csv" in page and "<a&b>" not in page  # names are escaped
    assert ("IN TOLERANCE" in page) == c.in_tolerance
    # deviation map, histogram and punch map, embedded
    assert page.count('src="data:image/png;base64,') == 3
    assert "Deviation at the punches" in page
    assert f"{c.rms_mm:.3f}" in page and "K9" in page


def test_report_without_punches_and_its_statistics_rows():
    _, _, c = sh.bump_result()
    page = comparison_report(c)
    assert "OUT OF TOLERANCE" in page and not c.in_tolerance  # the 5 mm bump
    assert page.count('src="data:image/png;base64,') == 2
    assert "Deviation at the punches" not in page
    rows = dict((name, value) for name, value, _ in statistics_rows(c))
    assert rows["RMS deviation"] == c.rms_mm and rows["points used (inliers)"] == c.n_inliers


def test_table_cells_format_numbers_and_escape_text():
    html = table_html([("a<b", 1.23456, 7, float("nan"), np.float64(2.0))], header=("x", "y", "z", "w", "v"))
    assert "<td>a&lt;b</td>" in html
    assert '<td class="num">1.235</td>' in html and '<td class="num">7</td>' in html
    assert '<td class="num">-</td>' in html and '<td class="num">2.000</td>' in html
    assert html.count("<th>") == 5
