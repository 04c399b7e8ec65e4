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


@pytest.fixture(scope="module")
def files(tmp_path_factory, hull_dir):
    """The K3 hull plate as design, a moved noisy scan of it with a few outliers."""
    folder = tmp_path_factory.mktemp("compare")
    design = hull_dir / "K3_stern_saddle.csv"
    points = read_points(design).points
    rng = np.random.default_rng(3)
    tf = make_tf(Rotation.from_euler("xyz", [10, 50, -30], degrees=True).as_matrix(), [100.0, 200.0, 300.0])
    scan = apply_tf(tf, points + rng.normal(0.0, 0.3, points.shape))
    scan[::97] += 30.0
    return {
        "design": str(design),
        "scan": str(write_points(folder / "scan.ply", scan)),
        "scan_m": str(write_points(folder / "scan_m.csv", scan / 1000.0)),  # a scan exported in metres
        "other": str(hull_dir / "K1_midbody_bilge.csv"),
        "folder": folder,
    }


def test_json_plot_and_report(files, capsys):
    plot = files["folder"] / "deviation.png"
    report = files["folder"] / "report.html"
    code = main(["compare", files["design"], files["scan"], "--json", "--plot", str(plot), "--report", str(report),
                 "--tolerance", "2.0"])
    out = capsys.readouterr().out
    assert code == 0
    doc = json.loads(out)
    for key in ("rms_mm", "max_abs_mm", "within_tolerance_pct", "transform", "histogram", "n_outliers"):
        assert key in doc
    assert np.array(doc["transform"]).shape == (4, 4)
    assert doc["rms_mm"] == pytest.approx(0.3, abs=0.05)
    assert doc["within_tolerance_pct"] == 100.0
    assert doc["tolerance_mm"] == 2.0
    assert doc["n_outliers"] >= 20  # 26 points were thrown 30 mm off
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    page = report.read_text()
    assert page.startswith("<!DOCTYPE html>")
    assert page.count('src="data:image/png;base64,') >= 2  # deviation map and histogram
    assert "<table>" in page and "RMS deviation" in page and "IN TOLERANCE" in page


def test_table_and_ascii_histogram(files, capsys):
    code = main(["compare", files["design"], files["scan"], "--thickness", "20", "--skin", "mid"])
    out = capsys.readouterr().out
    assert code == 0
    for text in ("RMS deviation", "largest |deviation|", "within +-2.5 mm", "registration RMS",
                 "deviation histogram", "#"):
        assert text in out


def test_skin_offset(files, capsys):
    code = main(["compare", files["design"], files["scan"], "--json", "--thickness", "20", "--skin", "top"])
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
    assert len(err.strip().splitlines()) == 1
    code = main(["compare", design, scan, "--margin", "100", "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 0
    assert doc["margin_mm"] == 100.0
    assert doc["n_margin"] > 500
    assert doc["rms_mm"] == pytest.approx(0.2, abs=0.03)
    code = main(["compare", design, scan, "--margin", "100"])
    out = capsys.readouterr().out
    assert code == 0 and "trim margin" in out
