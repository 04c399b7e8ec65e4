"""``mppf plan`` on the command line: outputs, exit codes, nothing written on errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mppf.cli import main
from mppf.geometry.read import read_points
from mppf.geometry.write import write_points
from mppf.planning.job import load_job
from mppf.model.press import example_press_path
from mppf.geometry.unfold import unfold


@pytest.fixture(scope="module")
def plate_files(tmp_path_factory, hull_dir):
    """A real hull patch and its unfolded flat plate as files."""
    folder = tmp_path_factory.mktemp("plan_cli")
    design = hull_dir / "P2_bow_flare_smooth.csv"
    flat = write_points(folder / "P2_flat.csv", unfold(read_points(design).points).flat)
    return design, flat


def _press_file(tmp_path, replace: tuple[str, ...] | None = None):
    text = example_press_path().read_text()
    for old, new in zip((replace or ())[::2], (replace or ())[1::2]):
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / "press.toml"
    path.write_text(text)
    return path


def test_plan_writes_job_plot_and_json(plate_files, tmp_path, capsys):
    design, flat = plate_files
    job_path, png = tmp_path / "job.json", tmp_path / "strokes.png"
    code = main(["plan", str(design), str(flat), "--thickness", "20", "-o", str(job_path),
                 "--plot", str(png), "--json"])
    out = capsys.readouterr().out
    assert code == 0
    summary = json.loads(out)
    job = load_job(job_path)
    assert summary["n_steps"] == len(job.steps)
    assert summary["upper"]["active"] == int(job.steps[-1].active.sum())
    assert summary["job"]["sha256"] == job.sha256()
    assert len(summary["plate_corners_mm"]) == 4
    assert job.reports.inputs.design.sha256 == read_points(design).sha256
    assert job.reports.inputs.flat.path == str(flat)
    assert png.stat().st_size > 10_000 and png.read_bytes()[:4] == b"\x89PNG"


def test_plan_prints_tables(plate_files, capsys):
    design, flat = plate_files
    assert main(["plan", str(design), str(flat), "--thickness", "20", "--steps", "2"]) == 0
    out = capsys.readouterr().out
    for text in ("registration", "largest punch travel", "upper", "lower", "corner"):
        assert text in out


def test_plan_with_springback(plate_files, tmp_path, capsys):
    design, flat = plate_files
    job_path = tmp_path / "job.json"
    assert main(["plan", str(design), str(flat), "--thickness", "20", "--springback", "--material", "ah36",
                 "-o", str(job_path), "--json"]) == 0
    job = load_job(job_path)
    assert job.reports.springback.enabled
    assert job.layout.material.yield_stress_mpa == 355.0


@pytest.mark.parametrize(
    "args, replace, message",
    [
        (["--thickness", "0"], None, "thickness"),
        (["--thickness", "-3"], None, "thickness"),
        (["--thickness", "20", "--springback"], None, "material"),
        (["--thickness", "20"], ("tip_radius_mm = 60.0", "tip_radus_mm = 60.0"), "unknown key"),
        (["--thickness", "20"], ("pitch_y_mm = 150.0", ""), "missing key 'pitch_y_mm'"),
        (["--thickness", "20"], ("rows = 16", 'rows = "16"'), "whole number"),
        (["--thickness", "20"], ("max_mm = 300.0", "max_mm = 10.0", "-400.0", "-10.0"),
         "beyond the press limits"),
    ],
)
def test_bad_input_exits_2_and_writes_nothing(plate_files, tmp_path, capsys, args, replace, message):
    design, flat = plate_files
    job_path = tmp_path / "job.json"
    press = _press_file(tmp_path, replace)
    code = main(["plan", str(design), str(flat), "--press", str(press), *args, "-o", str(job_path),
                 "--plot", str(tmp_path / "s.png")])
    err = capsys.readouterr().err
    assert code == 2
    assert message in " ".join(err.split())
    assert "Traceback" not in err
    assert not job_path.exists() and not (tmp_path / "s.png").exists()


def test_flat_of_another_plate_exits_2(plate_files, hull_dir, tmp_path, capsys):
    _, flat = plate_files
    job_path = tmp_path / "job.json"
    code = main(["plan", str(hull_dir / "K1_midbody_bilge.csv"), str(flat), "--thickness", "20",
                 "-o", str(job_path)])
    assert code == 2
    assert "does not belong" in capsys.readouterr().err
    assert not job_path.exists()


def test_too_few_steps_exits_2(hull_dir, tmp_path, capsys):
    design = hull_dir / "K1_midbody_bilge.csv"
    flat = write_points(tmp_path / "flat.csv", unfold(read_points(design).points).flat)
    job_path = tmp_path / "job.json"
    code = main(["plan", str(design), str(flat), "--thickness", "20", "--steps", "1", "-o", str(job_path)])
    err = " ".join(capsys.readouterr().err.split())
    assert code == 2
    assert "dimpling limit" in err and "upper punches (row " in err
    assert not job_path.exists()
    assert main(["plan", str(design), str(flat), "--thickness", "20", "-o", str(job_path), "--json"]) == 0
    job = load_job(job_path)
    assert len(job.steps) >= 2
    steps = np.array([s.upper_mm for s in job.steps])
    assert np.all(np.isfinite(steps[:, job.steps[-1].active]))


def test_units_in_metres(plate_files, tmp_path, capsys):
    design, flat = plate_files
    design_m = write_points(tmp_path / "design_m.csv", read_points(design).points / 1000.0)
    flat_m = write_points(tmp_path / "flat_m.csv", read_points(flat).points / 1000.0)
    assert main(["plan", str(design_m), str(flat_m), "--thickness", "20", "--units", "m", "--json"]) == 0
    in_m = json.loads(capsys.readouterr().out)
    assert main(["plan", str(design), str(flat), "--thickness", "20", "--json"]) == 0
    in_mm = json.loads(capsys.readouterr().out)
    assert in_m["max_travel_mm"] == pytest.approx(in_mm["max_travel_mm"], abs=1e-3)
