"""``--yield-uncertainty`` on ``mppf plan`` and ``mppf loop``: the first press under-bends (issue 40)."""

from __future__ import annotations

import json

import pytest
from plan_helpers import cylinder_points, developed_cylinder

from mppf.cli import main
from mppf.forming.material import DEFAULT_YIELD_UNCERTAINTY_PCT
from mppf.geometry.write import write_points
from mppf.model.press import example_press_path
from mppf.planning.job import load_job

RADIUS_MM = 4000.0


@pytest.fixture(scope="module")
def cylinder_files(tmp_path_factory):
    """A 2.8 x 1.5 m cylinder plate of radius 4 m and its developed flat, as files."""
    folder = tmp_path_factory.mktemp("first_press")
    design = write_points(folder / "design.csv", cylinder_points(RADIUS_MM, 2800.0, 1500.0))
    flat = write_points(folder / "flat.csv", developed_cylinder(RADIUS_MM, 2800.0, 1500.0))
    return design, flat


def _plan(files, tmp_path, capsys, *options):
    design, flat = files
    job_path = tmp_path / "job.json"
    code = main(["plan", str(design), str(flat), "--thickness", "20", "--margin", "0", "--springback",
                 "--material", "steel", "-o", str(job_path), "--json", *options])
    captured = capsys.readouterr()
    return code, captured, job_path


def test_plan_records_the_declared_uncertainty_in_the_sealed_job(cylinder_files, tmp_path, capsys):
    code, captured, job_path = _plan(cylinder_files, tmp_path, capsys, "--yield-uncertainty", "10")
    assert code == 0, captured.err
    first = json.loads(captured.out)["springback"]["first_press"]
    assert first["yield_uncertainty_pct"] == 10.0
    assert first["planned_yield_mpa"] == pytest.approx(211.5)
    job = load_job(job_path)  # the seal holds it
    assert job.reports.springback.first_press.to_doc() == first
    assert job.layout.material.yield_stress_mpa == 235.0
    loaded_weak = min(abs(r) for r in job.reports.springback.loaded_radii_mm if r)
    code, captured, job_path = _plan(cylinder_files, tmp_path, capsys)  # the default with --springback
    assert code == 0, captured.err
    job = load_job(job_path)
    first = job.reports.springback.first_press.to_doc()
    assert first["yield_uncertainty_pct"] == DEFAULT_YIELD_UNCERTAINTY_PCT
    assert first["planned_yield_mpa"] == pytest.approx(235.0 * (1 - DEFAULT_YIELD_UNCERTAINTY_PCT / 100))
    # planned for the weakest plate of a 10 % range, the loaded arc is gentler than the default's
    assert min(abs(r) for r in job.reports.springback.loaded_radii_mm if r) < loaded_weak - 50.0 \
        * (10.0 - DEFAULT_YIELD_UNCERTAINTY_PCT) / 10.0


def test_plan_table_names_the_planned_yield_stress(cylinder_files, capsys):
    design, flat = cylinder_files
    assert main(["plan", str(design), str(flat), "--thickness", "20", "--springback", "--material", "ah36",
                 "--yield-uncertainty", "5"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "337 MPa (nominal 355 - 5 %: under-bent)" in out


@pytest.mark.parametrize("value, message", [
    ("-5", "got -5"), ("50", "got 50"), ("nan", "got nan"), ("1e400", "got inf")])
def test_plan_refuses_bad_values_with_one_message(cylinder_files, tmp_path, capsys, value, message):
    code, captured, job_path = _plan(cylinder_files, tmp_path, capsys, "--yield-uncertainty", value)
    err = " ".join(captured.err.split())
    assert code == 2
    assert "yield-stress uncertainty (--yield-uncertainty)" in err and message in err
    assert "e.g. 10" in err
    assert "Traceback" not in err and not job_path.exists()


def test_plan_refuses_the_uncertainty_without_springback(cylinder_files, tmp_path, capsys):
    design, flat = cylinder_files
    code = main(["plan", str(design), str(flat), "--thickness", "20", "--yield-uncertainty", "10",
                 "-o", str(tmp_path / "job.json")])
    err = " ".join(capsys.readouterr().err.split())
    assert code == 2
    assert "has no effect without --springback" in err and "Traceback" not in err
    assert not (tmp_path / "job.json").exists()


@pytest.mark.parametrize("value", ["-1", "60", "nan"])
def test_loop_refuses_bad_values_before_anything_is_recorded(cylinder_files, tmp_path, capsys, value):
    design, flat = cylinder_files
    history = tmp_path / "history.sqlite"
    code = main(["loop", str(design), str(flat), "--press", str(example_press_path()), "--thickness", "20",
                 "--history", str(history), "--yield-uncertainty", value])
    err = " ".join(capsys.readouterr().err.split())
    assert code == 2
    assert "--yield-uncertainty" in err and f"got {value}" in err and "Traceback" not in err
    assert not history.exists()


@pytest.mark.slow  # one simulated cycle of a hull plate, compared on a dense scan: 5-15 s
def test_loop_plans_its_first_press_for_the_weakest_plate_and_records_it(hull_dir, tmp_path, capsys):
    from mppf.geometry.read import read_points
    from mppf.geometry.unfold import unfold
    from mppf.loop.history import History

    design = hull_dir / "P2_bow_flare_smooth.csv"
    flat = write_points(tmp_path / "P2_flat.csv", unfold(read_points(design).points).flat)
    history_path = tmp_path / "history.sqlite"
    code = main(["loop", str(design), str(flat), "--press", str(example_press_path()), "--thickness", "20",
                 "--history", str(history_path), "--time-scale", "200", "--max-cycles", "1", "--json",
                 "--no-report", "--plate-id", "P2-U10", "--yield-uncertainty", "10"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 5 and doc["status"] == "max_cycles"  # one press: not in tolerance
    with History(history_path) as history:
        assert history.plate("P2-U10").settings["loop"]["yield_uncertainty_pct"] == 10.0
        job = load_job(history.cycle("P2-U10", 1).job_path)
    first = job.reports.springback.first_press.to_doc()
    assert first["yield_uncertainty_pct"] == 10.0 and first["planned_yield_mpa"] == pytest.approx(211.5)
    assert job.layout.material.yield_stress_mpa == 235.0
