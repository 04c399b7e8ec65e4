"""The summary of a batch (:mod:`mppf.planning.batch`): one row per plate, as CSV and as an HTML page."""

from __future__ import annotations

import csv
import html
from pathlib import Path

from mppf.core.errors import InputError

COLUMNS = ("plate", "status", "length_mm", "width_mm", "thickness_mm", "sections", "steps", "max_travel_mm",
           "strain_pct", "border_step_mm", "warnings", "reason", "time_s", "cpu_s", "peak_rss_mb", "job")
"""Columns of the summary, in order (empty where a failed plate has no value)."""


def totals(rows: list[dict]) -> dict:
    """How many plates were planned, skipped and failed, and the sections and steps of the batch."""
    count = {s: sum(r["status"] == s for r in rows) for s in ("planned", "skipped", "failed")}
    ok = [r for r in rows if r["status"] != "failed"]
    return {"plates": len(rows), **count, "sections": sum(int(r.get("sections") or 0) for r in ok),
            "steps": sum(int(r.get("steps") or 0) for r in ok),
            "time_s": round(sum(float(r.get("time_s") or 0.0) for r in rows if r["status"] == "planned"), 2)}


def write_csv(rows: list[dict], path) -> Path:
    """The summary as CSV (``COLUMNS``), written atomically."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    try:
        with tmp.open("w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=COLUMNS, extrasaction="ignore")
            writer.writeheader()
            for row in rows:
                writer.writerow({k: "" if row.get(k) is None else row.get(k) for k in COLUMNS})
        tmp.replace(path)
    except OSError as exc:
        raise InputError(f"cannot write the batch summary {path}: {exc.strerror}",
                         hint="choose a writable -o") from None
    return path


def write_html(rows: list[dict], path, title: str = "mppf batch") -> Path:
    """The summary as one self-contained HTML page: the totals, then a table (failed plates in red)."""
    path = Path(path)
    t = totals(rows)
    head = "".join(f"<th>{html.escape(c)}</th>" for c in COLUMNS)
    body = []
    for row in rows:
        cls = f' class="{row["status"]}"'
        cells = "".join(f"<td>{html.escape('' if row.get(c) is None else str(row.get(c)))}</td>" for c in COLUMNS)
        body.append(f"<tr{cls}>{cells}</tr>")
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>body{{font-family:sans-serif}} table{{border-collapse:collapse}} td,th{{border:1px solid #999;padding:2px 6px}}
tr.failed{{background:#fdd}} tr.skipped{{color:#555}}</style></head>
<body><h1>{html.escape(title)}</h1>
<p>{t['plates']} plates: {t['planned']} planned, {t['skipped']} skipped (unchanged), {t['failed']} failed;
{t['sections']} sections, {t['steps']} press steps; planning time {t['time_s']} s (sum over plates).</p>
<table><thead><tr>{head}</tr></thead><tbody>
{chr(10).join(body)}
</tbody></table></body></html>
"""
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_text(page)
        tmp.replace(path)
    except OSError as exc:
        raise InputError(f"cannot write the batch summary {path}: {exc.strerror}",
                         hint="choose a writable -o") from None
    return path
