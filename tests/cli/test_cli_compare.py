"""``mppf compare`` on the command line: output, JSON, pictures, report, exit codes."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import margin_helpers as mh
from mppf.cli import main
from mppf.geometry.read import read_points
from mppf.geometry.write import write_points
from mppf.core.transform import apply_tf, make_tf


def dense_copy(points: np.ndarray, shape=(61, 41), factor: int = 3) -> np.ndarray:
    """The surface of a (rows, cols) grid of points resampled ``factor`` times finer (cubic splines of the grid)."""
    from scipy.interpolate import RectBivariateSpline

    rows, cols = shape
    grid = points.reshape(rows, cols, 3)
    i, j = np.arange(rows), np.arange(cols)
    fine_i, fine_j = np.linspace(0, rows - 1, factor * (rows - 1) + 1), np.linspace(0, cols - 1, factor * (cols - 1) + 1)
    return np.stack([RectBivariateSpline(i, j, grid[..., k])(fine_i, fine_j).ravel() for k in range(3)], axis=1)


@pytest.fixture(scope="module")
def files(tmp_path_factory, hull_dir):
    """The K3 hull plate as design, a moved noisy dense scan of it (3 x its grid) with a few scanner artefacts.

    Dense: artefacts are set aside only where the scan's neighbours contradict them (issue 13); on the design's own
    50 mm grid nothing would be set aside.
    """
    folder = tmp_path_factory.mktemp("compare")
    design = hull_dir / "K3_stern_saddle.csv"
    points = dense_copy(read_points(design).points)
    rng = np.random.default_rng(3)
    tf = make_tf(Rotation.from_euler("xyz", [10, 50, -30], degrees=True).as_matrix(), [100.0, 200.0, 300.0])
    scan = apply_tf(tf, points + rng.normal(0.0, 0.3, points.shape))
    scan[::97] += 30.0
    # the tests of the output's form (table, skin, units, export) need no artefacts: a clean scan 2 x the grid,
    # registered in a third of the time
    plain = apply_tf(tf, dense_copy(read_points(design).points, factor=2))
    plain += rng.normal(0.0, 0.3, plain.shape)
    return {
        "design": str(design),
        "scan": str(write_points(folder / "scan.ply", scan)),
        "scan_m": str(write_points(folder / "scan_m.csv", scan / 1000.0)),  # a scan exported in metres
        "plain": str(write_points(folder / "plain.ply", plain)),
        "plain_m": str(write_points(folder / "plain_m.csv", plain / 1000.0)),
        "other": str(hull_dir / "K1_midbody_bilge.csv"),
        "folder": folder,
    }


def test_json_plot_and_report(files, capsys):
    plot = files["folder"] / "deviation.png"
    report = files["folder"] / "report.html"
    code = main(["compare", files["design"], files["scan"], "--json", "--plot", str(plot), "--report", str(report),
                 "--tolerance", "2.0"])
    out = capsys.readouterr().out
    assert code == 6  # needs review (README, "Exit codes")
    doc = json.loads(out)
    for key in ("rms_mm", "max_abs_mm", "within_tolerance_pct", "transform", "histogram", "n_outliers"):
        assert key in doc
    assert np.array(doc["transform"]).shape == (4, 4)
    assert doc["rms_mm"] == pytest.approx(0.3, abs=0.05)
    # every net point counts in the share within the tolerance, the 225 set aside 30 mm off too
    assert doc["within_tolerance_pct"] == pytest.approx(100.0 * (1 - 1 / 97), abs=0.2)
    assert doc["tolerance_mm"] == 2.0
    assert doc["n_outliers"] >= 200  # 225 points were thrown 30 mm off
    assert doc["verdict"]["kind"] == "needs_review"  # set-aside points beyond the tolerance: a person looks
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    page = report.read_text()
    assert page.startswith("<!DOCTYPE html>")
    assert page.count('src="data:image/png;base64,') >= 2  # deviation map and histogram
    assert "<table>" in page and "RMS deviation" in page and "NEEDS REVIEW" in page and "form max" in page


def test_table_and_ascii_histogram(files, capsys):
    code = main(["compare", files["design"], files["plain"], "--thickness", "20", "--skin", "mid"])
    out = capsys.readouterr().out
    assert code == 0
    for text in ("RMS deviation", "largest |deviation|", "within +-2.5 mm", "registration RMS",
                 "deviation histogram", "#"):
        assert text in out


def test_skin_offset(files, capsys):
    code = main(["compare", files["design"], files["plain"], "--json", "--thickness", "20", "--skin", "top"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 0
    assert doc["offset_mm"] == 10.0 and doc["skin"] == "top"
    # the scan is of the mid-surface: registered to the top skin, the rigid fit absorbs the offset
    assert doc["rms_mm"] < 1.0


@pytest.mark.parametrize(
    "args, message",
    [
        (["missing.csv", "{scan}"], "not found"),
        (["{design}", "{bad}"], "line"),
        (["{design}", "{scan_m}"], "units"),
        (["{design}", "{scan}", "--skin", "top"], "--thickness"),
        (["{design}", "{scan}", "--tolerance", "-1"], "tolerance"),
        (["{design}", "{scan}", "--plot", "map.foo"], "picture type"),
    ],
)
def test_bad_files_and_options_exit_2(files, capsys, args, message):
    bad = files["folder"] / "bad.csv"
    bad.write_text("x,y,z\n1,2,3\n4,five,6\n")
    names = dict(files, bad=str(bad))
    argv = ["compare", *[a.format(**names) for a in args]]
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2
    assert message in err
    assert "Traceback" not in err


def test_mismatched_plate_exits_2(files, capsys):
    code = main(["compare", files["design"], files["other"]])
    err = capsys.readouterr().err
    assert code == 2
    assert "does not match" in err


def test_unwritable_report_exits_2(files, capsys, tmp_path):
    code = main(["compare", files["design"], files["scan"], "--report", str(tmp_path / "no" / "such" / "r.html")])
    assert code == 2
    assert "cannot write" in capsys.readouterr().err


@pytest.fixture(scope="module")
def margin_files(tmp_path_factory):
    """A scan of the gross plate (net design + a 100 mm band) and its net design (tests/margin_helpers.py)."""
    folder = tmp_path_factory.mktemp("margin")
    _, _, scan = mh.scan(n=6000)
    return (str(write_points(folder / "design.csv", mh.design())), str(write_points(folder / "scan.csv", scan)))


def test_cli_margin(margin_files, capsys):
    design, scan = margin_files
    code = main(["compare", design, scan, "--margin", "-1"])
    err = capsys.readouterr().err
    assert code == 2
    assert "--margin" in err and "-1" in err and "Traceback" not in err
    lines = err.strip().splitlines()  # one message: what was wrong and the value, then what to do
    assert len(lines) <= 2 and lines[0].startswith("error:") and all("what to do" in line for line in lines[1:])
    code = main(["compare", design, scan, "--margin", "100", "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 0
    assert doc["margin_mm"] == 100.0
    assert doc["n_margin"] > 500
    assert doc["rms_mm"] == pytest.approx(0.2, abs=0.03)
    code = main(["compare", design, scan, "--margin", "100"])
    out = capsys.readouterr().out
    assert code == 0 and "trim margin" in out


def test_scan_units_export_and_scale(files, capsys):
    """A scan in metres beside a design in mm (--scan-units); the per-point export; a fixed colour scale."""
    export = files["folder"] / "points.ply"
    plot = files["folder"] / "scaled.png"
    code = main(["compare", files["design"], files["plain_m"], "--scan-units", "m", "--json", "--export", str(export),
                 "--plot", str(plot), "--scale", "4"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 0
    assert doc["rms_mm"] == pytest.approx(0.3, abs=0.05)
    assert export.read_bytes().startswith(b"ply\nformat binary_little_endian")
    assert b"property double scalar_deviation" in export.read_bytes()[:1000]
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    code = main(["compare", files["design"], files["scan"], "--export", str(files["folder"] / "points.txt")])
    assert code == 2 and ".ply" in capsys.readouterr().err


def test_bad_mark_exits_2(files, capsys):
    code = main(["compare", files["design"], files["scan"], "--mark", "1,2"])
    err = capsys.readouterr().err
    assert code == 2 and "--mark" in err and "X,Y,Z" in err


def test_symmetric_plate_without_mark_exits_4_with_both_candidates(tmp_path, capsys):
    import scan_helpers as sh
    from mppf.model.job_parts import reference_corner_xy
    from mppf.sim.scanner import SimulatedScanner

    formed = sh.form(8000.0, 18000.0, asymmetric=False)
    design = write_points(tmp_path / "design.csv", formed.mid_surface_points(50.0))
    sample = SimulatedScanner(seed=4).sample(formed, reference_corner_xy(formed.outline_xy_mm))
    scan = write_points(tmp_path / "scan.csv", sample.points)
    args = ["compare", str(design), str(scan), "--thickness", "20", "--skin", "top"]
    code = main(args)
    err = capsys.readouterr().err
    assert code == 4
    assert "ambiguous: give the reference mark" in err and err.count("residual") >= 2
    # the mark on the command line settles it
    mark = ",".join(f"{v:.3f}" for v in sample.mark_mm)
    code = main([*args, "--mark", mark, "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert code == {"in_tolerance": 0, "out_of_tolerance": 5, "needs_review": 6}[doc["verdict"]["kind"]]
    assert doc["registration"]["ambiguous_start"] is True
    assert doc["registration"]["init"]["settled_by"] in ("mark", "held mark")


def test_job_gives_what_the_loop_uses(planned_plate, tmp_path, capsys):
    """``compare --job`` judges with the loop's keywords (mppf.measure.job_options): the same verdict and figures."""
    from mppf.measure.compare import compare
    from mppf.measure.job_options import job_compare_options
    from mppf.planning.job import save_job

    design, _, _, job = planned_plate
    job_path = save_job(job, tmp_path / "job.json")
    rng = np.random.default_rng(8)
    tf = make_tf(Rotation.from_euler("xyz", [3, -2, 40], degrees=True).as_matrix(), [50.0, -80.0, 120.0])
    dense = dense_copy(design.points, factor=2)  # the same figures both ways at any density: 2 x the grid is enough
    scan_points = apply_tf(tf, dense + rng.normal(0.0, 0.2, dense.shape))
    scan = write_points(tmp_path / "scan.csv", scan_points)
    design_path = write_points(tmp_path / "design.csv", design.points)
    code = main(["compare", str(design_path), str(scan), "--job", str(job_path), "--skin", "mid", "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 0
    assert doc["job"] == str(job_path) and doc["margin_mm"] == job.layout.margin_mm
    assert "punch_deviation_mm" in doc  # the job's punch grid
    options = job_compare_options(job, design.points, scan, offset_mm=0.0)
    direct = compare(design.points, read_points(scan).points, options)
    assert doc["verdict"]["kind"] == direct.verdict.kind
    assert doc["rms_mm"] == pytest.approx(direct.rms_mm, abs=1e-6)
    assert doc["form_max_abs_mm"] == pytest.approx(direct.form_max_abs_mm, abs=1e-6)
