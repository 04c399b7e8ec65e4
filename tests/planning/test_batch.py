"""Batch planning: manifest, resumable runs in a pool, failures as rows, summaries."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from mppf.core.errors import FileFormatError, InputError
from mppf.examples.analytic import cylinder_plate
from mppf.geometry.write import write_points
from mppf.model.press import example_press_path
from mppf.planning.batch import BatchOptions, input_key, plates_from_files, read_manifest, run_batch
from mppf.planning.batch_summary import COLUMNS, totals, write_csv, write_html
from mppf.planning.job import load_job


@pytest.fixture(scope="module")
def plate_dir(tmp_path_factory):
    """A short plate (fits the bed), a long one with its exact flat, and a file that is no plate."""
    folder = tmp_path_factory.mktemp("plates")
    short, _ = cylinder_plate(3000.0, 2000.0, 9000.0, spacing_mm=150.0)
    long_design, long_flat = cylinder_plate(5000.0, 2000.0, 15000.0, spacing_mm=150.0)
    write_points(folder / "short.csv", short)
    write_points(folder / "long.csv", long_design)
    write_points(folder / "long_flat.csv", long_flat)
    (folder / "broken.csv").write_text("x,y,z\n1,2\n")
    (folder / "plates.csv").write_text("name,design,flat,thickness_mm,material,springback\n"
                                       "S1,short.csv,,20,steel,no\n"
                                       "L1,long.csv,long_flat.csv,18,,\n"
                                       "B1,broken.csv,,20,,\n")
    return folder


def _options(out, workers=1):
    return BatchOptions(press_path=str(example_press_path()), out_dir=str(out), workers=workers)


def test_manifest_rows_become_plates(plate_dir):
    plates = read_manifest(plate_dir / "plates.csv")
    assert [p.name for p in plates] == ["S1", "L1", "B1"]
    assert plates[0].material == "steel" and plates[0].springback is False and plates[0].flat is None
    assert plates[1].flat == str(plate_dir / "long_flat.csv") and plates[1].thickness_mm == 18.0


@pytest.mark.parametrize("row, message", [
    ("S1,short.csv,,thick,,", r"line 2: thickness_mm 'thick' is not a number"),
    ("S1,short.csv,,-3,,", r"line 2: thickness_mm"),
    ("S1,short.csv,,20,bronze,", r"material 'bronze' is not known"),
    ("S1,,,20,,", r"line 2: no design file"),
    ("S1,short.csv,,,,", r"line 2: no thickness_mm"),
])
def test_bad_manifest_rows_name_file_and_line(plate_dir, tmp_path, row, message):
    manifest = tmp_path / "m.csv"
    manifest.write_text("name,design,flat,thickness_mm,material,springback\n" + row + "\n")
    (tmp_path / "short.csv").write_bytes((plate_dir / "short.csv").read_bytes())
    with pytest.raises(FileFormatError, match=message):
        read_manifest(manifest)


def test_bad_batches_are_input_errors(plate_dir, tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        read_manifest(tmp_path / "none.csv")
    twice = tmp_path / "twice.csv"
    twice.write_text(f"name,design,thickness_mm\nA,{plate_dir / 'short.csv'},20\nA,{plate_dir / 'long.csv'},20\n")
    with pytest.raises(InputError, match="names must be unique, A"):
        read_manifest(twice)
    with pytest.raises(InputError, match="do not exist: .*nope.csv"):
        plates_from_files([str(tmp_path / "nope.csv")], 20.0)
    with pytest.raises(InputError, match="thickness is missing"):
        plates_from_files([str(plate_dir / "short.csv")], None)


def test_batch_plans_skips_and_reports_failures(plate_dir, tmp_path):
    plates = read_manifest(plate_dir / "plates.csv")
    rows = run_batch(plates, _options(tmp_path))
    by_name = {r["plate"]: r for r in rows}
    assert [r["plate"] for r in rows] == ["S1", "L1", "B1"]
    assert by_name["S1"]["status"] == "planned" and by_name["S1"]["sections"] == 1
    assert by_name["L1"]["status"] == "planned" and by_name["L1"]["sections"] == 2
    assert by_name["L1"]["border_step_mm"] < 0.2 and by_name["L1"]["steps"] >= 2
    assert by_name["B1"]["status"] == "failed" and "broken.csv" in by_name["B1"]["reason"]
    assert (tmp_path / "S1.flat.csv").is_file()  # unfolded in the batch
    long_job = load_job(tmp_path / "L1.job.json")
    assert len(long_job.sections) == 2 and long_job.batch.key == input_key(plates[1], _options(tmp_path))
    # run again: both finished plates are skipped, the broken one fails again
    again = run_batch(plates, _options(tmp_path))
    assert [r["status"] for r in again] == ["skipped", "skipped", "failed"]
    assert again[1]["sections"] == 2 and again[1]["max_travel_mm"] == by_name["L1"]["max_travel_mm"]
    # a changed input (thickness) is planned again
    thicker = [plates[0].__class__(**{**plates[0].__dict__, "thickness_mm": 22.0})]
    assert run_batch(thicker, _options(tmp_path))[0]["status"] == "planned"


def test_input_key_follows_the_files(plate_dir, tmp_path):
    copy = tmp_path / "short.csv"
    copy.write_bytes((plate_dir / "short.csv").read_bytes())
    plate = plates_from_files([str(copy)], 20.0)[0]
    key = input_key(plate, _options(tmp_path))
    assert key == input_key(plate, _options(tmp_path))
    copy.write_text(copy.read_text().replace("\n", "\n", 1) + "0,0,0\n")
    assert input_key(plate, _options(tmp_path)) != key


def test_pool_of_two_workers_gives_the_same_rows(plate_dir, tmp_path):
    plates = read_manifest(plate_dir / "plates.csv")[:2]
    rows = run_batch(plates, _options(tmp_path, workers=2))
    assert [r["status"] for r in rows] == ["planned", "planned"] and rows[1]["sections"] == 2


def test_batches_in_one_running_pool_start_no_pool_of_their_own(plate_dir, tmp_path, monkeypatch):
    import os

    from mppf.planning import batch

    plates = read_manifest(plate_dir / "plates.csv")[:2]
    with batch.planning_pool(2) as pool:
        monkeypatch.setattr(batch, "planning_pool", None)  # run_batch must not start one
        first = run_batch(plates[:1], _options(tmp_path, workers=2), pool=pool)
        second = run_batch(plates[1:], _options(tmp_path, workers=2), pool=pool)
        workers = {pool.submit(os.getpid).result() for _ in range(6)}
    assert [r["status"] for r in first + second] == ["planned", "planned"] and second[0]["sections"] == 2
    assert 1 <= len(workers) <= 2 and os.getpid() not in workers


def test_summary_files(tmp_path):
    rows = [{"plate": "A", "status": "planned", "sections": 2, "steps": 5, "time_s": 1.5, "cpu_s": 1.2,
             "max_travel_mm": 30.0},
            {"plate": "B<1>", "status": "failed", "reason": "bad & broken", "time_s": 0.1}]
    assert totals(rows) == {"plates": 2, "planned": 1, "skipped": 0, "failed": 1, "sections": 2, "steps": 5,
                            "time_s": 1.5}
    with write_csv(rows, tmp_path / "s.csv").open() as f:
        table = list(csv.DictReader(f))
    assert list(table[0]) == list(COLUMNS) and table[1]["reason"] == "bad & broken" and table[1]["steps"] == ""
    page = write_html(rows, tmp_path / "s.html").read_text()
    assert "B&lt;1&gt;" in page and "bad &amp; broken" in page and 'class="failed"' in page
    assert "1 planned, 0 skipped (unchanged), 1 failed" in page


def test_bundled_long_plates_are_the_analytic_ones_and_plan_in_a_batch(tmp_path):
    import numpy as np

    import mppf.examples.analytic as analytic
    from mppf.geometry.read import read_points

    folder = Path(analytic.__file__).parent / "long"
    design, flat = cylinder_plate(spacing_mm=100.0)
    assert np.allclose(read_points(folder / "long_cylinder_7500x2400_R20m.csv").points, design, atol=1e-9)
    assert np.allclose(read_points(folder / "long_cylinder_7500x2400_R20m_flat.csv").points, flat, atol=1e-9)
    assert (folder / "plates.csv").read_text() == analytic.MANIFEST
    rows = run_batch(read_manifest(folder / "plates.csv"), _options(tmp_path, workers=2))
    assert [(r["plate"], r["status"], r["sections"]) for r in rows] == [("long_cylinder", "planned", 6),
                                                                         ("twisted", "planned", 6),
                                                                         ("kcs_stern_bilge", "planned", 6)]
    assert all(r["border_step_mm"] < 0.2 for r in rows)
    # the real hull plate (cut from the KCS model): about 9.4 x 2.5 m unfolded, truly curved
    assert rows[2]["length_mm"] > 9000.0 and rows[2]["max_travel_mm"] > 50.0 and rows[2]["strain_pct"] < 0.5


def test_a_plan_that_steps_at_its_section_borders_is_a_warning_in_the_summary():
    from types import SimpleNamespace

    from mppf.model.job_provenance import SectionalSummary
    from mppf.model.job_reports import PlanReports
    from mppf.planning.batch import Plate, summary_row

    warning = "section 2: its strokes step by 5.5 mm at its border with the plate formed before it (limit 1 mm)"
    sectional = SectionalSummary(plate_size_mm=np.array([4200.0, 2400.0]), n_steps_total=4, max_travel_mm=120.0,
                                 max_border_step_mm=5.5, warnings=(warning,))
    job = SimpleNamespace(sectional=sectional, reports=PlanReports(), sections=[object(), object()], steps=[])
    row = summary_row(Plate(name="p", design="p.csv", flat=None, thickness_mm=20.0), job, 0.01, ["flat: fine"], 1.0,
                      1.0)
    assert row["warnings"] == f"flat: fine; {warning}" and row["border_step_mm"] == 5.5 and row["sections"] == 2


def test_a_finished_job_changed_after_its_seal_is_planned_again_and_said_so(plate_dir, tmp_path):
    import json

    plates = read_manifest(plate_dir / "plates.csv")[:1]
    run_batch(plates, _options(tmp_path))
    path = tmp_path / "S1.job.json"
    doc = json.loads(path.read_text())
    doc["thickness_mm"] = 19.0  # edited by hand in the output folder
    path.write_text(json.dumps(doc))
    (row,) = run_batch(plates, _options(tmp_path))
    assert row["status"] == "planned" and "had been changed after it was sealed" in row["warnings"]
    assert "changed: thickness" in row["warnings"]
    assert load_job(path).thickness_mm == 20.0  # the edited job was replaced by the plan
