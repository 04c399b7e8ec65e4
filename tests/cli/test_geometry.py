"""The ``mppf fit`` command."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np

from mppf.cli import main
from mppf.geometry.read import read_points
from mppf.geometry.write import write_points
from mppf.core.transform import apply_tf


def test_fit_json_on_a_hull_plate(hull_dir, capsys):
    path = hull_dir / "K2_fwd_bilge_convex.csv"
    assert main(["fit", str(path), "--degree", "3", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["n_points"] == 2501 and out["degree"] == 3 and out["kind"] == "poly"
    assert 0 < out["rms_mm"] < out["max_abs_mm"] < 5.0
    tf = np.array(out["tf_local_world"])
    assert tf.shape == (4, 4)
    np.testing.assert_allclose(tf[:3, :3], out["frame"]["axes"])
    # the transform maps the file's points into the frame: centred, flat in w
    local = apply_tf(tf, read_points(path).points)
    np.testing.assert_allclose(local.mean(axis=0), 0.0, atol=1e-6)
    assert np.ptp(local[:, 2]) < 100.0


def test_fit_auto_spline_and_units(tmp_path, hull_dir, capsys):
    pts_m = read_points(hull_dir / "P1_midbody_bilge_smooth.csv").points / 1000.0
    path = write_points(tmp_path / "p1_m.xyz", pts_m)
    assert main(["fit", str(path), "--units", "m", "--degree", "auto", "--json"]) == 0
    auto = json.loads(capsys.readouterr().out)
    assert auto["degree"] in (2, 3, 4) and set(auto["heldout_rms_mm"]) == {"2", "3", "4"}
    assert auto["rms_mm"] < 0.05  # mm, after scaling from metres
    assert main(["fit", str(path), "--units", "m", "--kind", "spline", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["kind"] == "spline"


def test_fit_table_output(hull_dir, capsys):
    assert main(["fit", str(hull_dir / "P3_stern_saddle_smooth.csv")]) == 0
    out = capsys.readouterr().out
    assert "residual RMS" in out and "axis n" in out and "polynomial (3, 3)" in out


def test_missing_file_exit_2(tmp_path, capsys):
    assert main(["fit", str(tmp_path / "none.csv")]) == 2
    err = capsys.readouterr().err
    assert "not found" in err and "Traceback" not in err


def test_bad_field_exit_2_names_the_line(tmp_path, capsys):
    path = tmp_path / "bad.csv"
    path.write_text("x,y,z\n1,2,3\n1,two,3\n")
    assert main(["fit", str(path)]) == 2
    assert "line 3" in capsys.readouterr().err


def test_collinear_plate_exit_2(tmp_path, capsys):
    t = np.linspace(0, 3000, 40)[:, None]
    path = write_points(tmp_path / "line.csv", t * [1.0, 0.5, 0.25])
    assert main(["fit", str(path)]) == 2
    assert "collinear" in capsys.readouterr().err


def test_folded_plate_exit_2(tmp_path, capsys):
    theta, y = np.meshgrid(np.radians(np.linspace(0, 300, 60)), np.linspace(0, 3000, 12))
    pts = np.column_stack([400 * np.sin(theta.ravel()), y.ravel(), 400 * (1 - np.cos(theta.ravel()))])
    path = write_points(tmp_path / "curl.csv", pts)
    assert main(["fit", str(path)]) == 2
    assert "folds over" in capsys.readouterr().err


def test_console_script_bad_degree_exit_2(hull_dir):
    proc = subprocess.run(
        [sys.executable, "-m", "mppf", "fit", str(hull_dir / "P1_midbody_bilge.csv"), "--degree", "7"],
        capture_output=True, text=True, timeout=60,
    )
    assert proc.returncode == 2
    assert "--degree" in proc.stderr and "Traceback" not in proc.stderr
