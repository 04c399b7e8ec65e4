"""HTML reports: one self-contained page, pictures embedded as base64 PNG, plain tables.

The page is built from escaped strings (``html.escape``); it needs no template engine
and no files beside it, so it can be mailed or archived with the plate's records.
:func:`comparison_report` makes the report of ``mppf compare``; :func:`render_page`,
:func:`table_html` and :func:`image_html` are the building blocks, also for other
reports (the loop's).
"""

from __future__ import annotations

import base64
import html
from collections.abc import Sequence

import numpy as np

from mppf import __version__
from mppf.measure.result import Comparison
from mppf.report.deviation import deviation_map_figure, figure_png, histogram_figure, punch_map_figure

_STYLE = """
body { font-family: sans-serif; margin: 2em; color: #222; max-width: 1100px; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 1.6em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; margin: 0.5em 0; }
th, td { border: 1px solid #bbb; padding: 0.25em 0.7em; text-align: left; }
td.num { text-align: right; font-family: monospace; }
th { background: #eee; }
.ok { color: #1a7f37; font-weight: bold; } .bad { color: #b42318; font-weight: bold; }
img { max-width: 100%; border: 1px solid #ddd; margin: 0.4em 0; }
.grid td { font-size: 0.8em; padding: 0.15em 0.35em; }
@page { size: A4; margin: 14mm; }
@media print {
  body { margin: 0; max-width: none; font-size: 10pt; }
  h1, h2 { break-after: avoid; page-break-after: avoid; }
  table, img, tr { break-inside: avoid; page-break-inside: avoid; }
  img { max-height: 240mm; }
}
"""


def _cell(value) -> str:
    if isinstance(value, (float, np.floating)):
        text = "-" if not np.isfinite(value) else f"{float(value):.3f}"
        return f'<td class="num">{html.escape(text)}</td>'
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        return f'<td class="num">{int(value)}</td>'
    return f"<td>{html.escape(str(value))}</td>"


def table_html(rows: Sequence[Sequence], header: Sequence[str] | None = None, css_class: str = "") -> str:
    """An HTML table; numbers right-aligned (3 decimals for floats), text escaped."""
    parts = [f'<table class="{html.escape(css_class)}">' if css_class else "<table>"]
    if header:
        parts.append("<tr>" + "".join(f"<th>{html.escape(str(h))}</th>" for h in header) + "</tr>")
    for row in rows:
        parts.append("<tr>" + "".join(_cell(v) for v in row) + "</tr>")
    parts.append("</table>")
    return "\n".join(parts)


def image_html(png: bytes, alt: str) -> str:
    """An <img> with the PNG embedded as a base64 data URI."""
    data = base64.b64encode(png).decode("ascii")
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{data}">'


def render_page(title: str, sections: Sequence[tuple[str, str]], intro: str = "") -> str:
    """A complete HTML page: a title, an optional intro paragraph, then (heading, body html) sections."""
    body = [f"<h1>{html.escape(title)}</h1>"]
    if intro:
        body.append(f"<p>{html.escape(intro)}</p>")
    for heading, content in sections:
        body.append(f"<h2>{html.escape(heading)}</h2>\n{content}")
    body.append(f"<p><small>mppf {html.escape(__version__)}</small></p>")
    return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            f"<title>{html.escape(title)}</title>\n<style>{_STYLE}</style>\n</head>\n<body>\n"
            + "\n".join(body) + "\n</body>\n</html>\n")


def statistics_rows(c: Comparison) -> list[tuple]:
    """The statistics of a comparison as (name, value, unit) rows."""
    rows = [
        ("RMS deviation", c.rms_mm, "mm"),
        (f"form max: largest absolute form deviation (decides with the RMS; limits {c.tolerance_mm:g} mm, "
         f"RMS {c.rms_tolerance_mm:g} mm)", c.form_max_abs_mm, "mm"),
        ("largest absolute deviation of a single point", c.max_abs_mm, "mm"),
        ("mean deviation", c.mean_mm, "mm"),
        ("standard deviation", c.std_mm, "mm"),
        (f"within tolerance +-{c.tolerance_mm:g} mm (all measured net points)", c.within_tolerance_pct, "%"),
        ("points measured", c.n_points, ""),
        ("points used (inliers)", c.n_inliers, ""),
        ("points set aside as scanner artefacts (decide when beyond the tolerance)", int(c.is_outlier.sum()), ""),
        ("points outside the design left out", int(c.is_outside.sum()), ""),
        ("skin offset from the design mid-surface", c.offset_mm, "mm"),
        ("design surface fit RMS", c.design_fit_rms_mm, "mm"),
    ]
    if c.set_aside is not None:
        rows.append(("set aside", c.set_aside.describe(c.tolerance_mm), ""))
    if c.form:
        rows += [("form smoothing: point spacing", c.form["spacing_mm"], "mm"),
                 ("form smoothing: noise of the deviations", c.form["noise_mm"], "mm"),
                 ("form smoothing: fit radii", ", ".join(f"{r:.0f}" for r in c.form["radius_mm"]), "mm")]
    return rows


def registration_rows(c: Comparison) -> list[tuple]:
    """The registration report as (name, value) rows."""
    r = c.registration
    rows = [
        ("method", f"ICP {r.method}-to-{'plane' if r.method == 'plane' else 'point'}, trimmed, Huber weights"),
        ("start", str(r.init.get("kind", "?"))),
        ("RMS of the matched pairs (mm)", r.rms_mm),
        ("iterations", r.iterations),
        ("converged", "yes" if r.converged else f"no ({r.stop_reason})"),
        ("judgement", r.judgement or "-"),
        ("residual against the noise floor (mm)", f"{r.residual_mm:.3f} / {r.noise_mm:.3f}"),
        ("start settled by", str(r.init.get("settled_by", "-"))),
        ("inlier fraction", r.inlier_fraction),
        ("ambiguous start (symmetric plate)", "yes - check the turn" if r.ambiguous_start else "no"),
    ]
    rows += [("note", n) for n in r.notes]
    return rows


def comparison_report(
    comparison: Comparison,
    *,
    title: str = "Plate deviation report",
    design_name: str = "",
    measured_name: str = "",
    punch_x_mm=None,
    punch_y_mm=None,
    extra_rows: Sequence[tuple] = (),
    scale_mm: float | None = None,
) -> str:
    """The HTML report of one comparison: verdict, statistics, pictures, registration, punches.

    Parameters
    ----------
    comparison : Comparison
    title : str
    design_name, measured_name : str
        What was compared (file names, hashes), shown in the summary.
    punch_x_mm, punch_y_mm : (cols,), (rows,) float, optional
        Punch axes, for the punch deviation map (when the comparison has punch values).
    extra_rows : sequence of (name, value)
        More lines for the summary table (plate id, cycle, operator...).
    scale_mm : float, optional
        Half range of the pictures' fixed colour scale (default 2 x the tolerance).

    Returns
    -------
    str
        The HTML document.
    """
    c = comparison
    verdict = f'<p class="{"ok" if c.in_tolerance else "bad"}">{html.escape(_headline(c))}</p>'
    summary = [("design", design_name or "-"), ("measured", measured_name or "-"), *extra_rows]
    sections = [
        ("Summary", verdict + table_html(summary)),
        ("Statistics", table_html(statistics_rows(c), header=("quantity", "value", "unit"))),
        ("Deviation map", image_html(figure_png(deviation_map_figure(c, scale_mm=scale_mm)), "deviation map")),
        ("Histogram", image_html(figure_png(histogram_figure(c)), "deviation histogram")
         + table_html(_histogram_rows(c), header=("from (mm)", "to (mm)", "points"))),
        ("Registration (measured to design)",
         table_html(registration_rows(c)) + "<p>Transform (measured to design, mm):</p>"
         + table_html([list(row) for row in np.asarray(c.transform)], css_class="grid")),
    ]
    if c.punch_deviation_mm is not None:
        body = ""
        if punch_x_mm is not None and punch_y_mm is not None:
            body += image_html(figure_png(punch_map_figure(c, punch_x_mm, punch_y_mm, scale_mm)),
                               "punch deviation map")
        base = c.punch_label_base
        rows = [[f"row {i + base}"] + [float(v) for v in row] for i, row in enumerate(c.punch_deviation_mm)]
        header = ["", *(f"col {j + base}" for j in range(c.punch_deviation_mm.shape[1]))]
        body += ("<p>Deviation at each punch along press z (mm; positive = plate above the design; "
                 "- = off the plate).</p>" + table_html(rows, header=header, css_class="grid"))
        sections.append(("Deviation at the punches", body))
    if c.notes:
        sections.append(("Notes", "<ul>" + "".join(f"<li>{html.escape(n)}</li>" for n in c.notes) + "</ul>"))
    return render_page(title, sections)


def _headline(c: Comparison) -> str:
    """The verdict in capitals and the figures that decided it."""
    if c.verdict is None:
        return c.headline
    return f"{c.verdict.label.upper()}: {'; '.join(c.verdict.reasons)}"


def _histogram_rows(c: Comparison) -> list[tuple]:
    e = c.histogram_edges_mm
    return [(float(e[i]), float(e[i + 1]), int(n)) for i, n in enumerate(c.histogram_counts)]
