"""``mppf register`` on files."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mppf.cli import main
from mppf.geometry.read import read_points
from mppf.geometry.write import write_points
from mppf.core.transform import apply_tf, make_tf


@pytest.fixture()
def pair_files(tmp_path, hull_dir):
    source = read_points(hull_dir / "P2_bow_flare.csv").points
    tf_true = make_tf(Rotation.from_euler("xyz", [10, -20, 30], degrees=True).as_matrix(), [100, -200, 300])
    rng = np.random.default_rng(5)
    target = apply_tf(tf_true, source) + rng.normal(scale=0.5, size=source.shape)
    src_path = write_points(tmp_path / "scan.csv", source)
    tgt_path = write_points(tmp_path / "design.xyz", target)
    return src_path, tgt_path, tf_true, source


@pytest.mark.parametrize("method", ["paired", "point", "plane"])
def test_register_json(pair_files, capsys, method):
    src_path, tgt_path, tf_true, _ = pair_files
    code = main(["register", str(src_path), str(tgt_path), "--method", method, "--json"])
    assert code == 0
    data = json.loads(capsys.readouterr().out)
    for key in ("rms_mm", "iterations", "transform", "method", "converged", "stop_reason", "inlier_fraction"):
        assert key in data
    assert data["method"] == method
    tf = np.array(data["transform"])
    assert tf.shape == (4, 4)
    assert np.allclose(tf[:3, :3], tf_true[:3, :3], atol=1e-3)
    assert 0.3 < data["rms_mm"] < 1.1


def test_register_table_and_moved_output(pair_files, capsys, tmp_path):
    src_path, tgt_path, tf_true, source = pair_files
    out = tmp_path / "moved.csv"
    code = main(["register", str(src_path), str(tgt_path), "-o", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    for words in ("RMS", "iterations", "converged", "inlier fraction", "transform", "judgement",
                  "residual / noise floor", "starts tried"):
        assert words in text
    moved = read_points(out).points
    assert moved.shape == source.shape
    assert np.abs(moved - apply_tf(tf_true, source)).max() < 2.0


def test_register_units_m(pair_files, capsys, tmp_path):
    src_path, tgt_path, _, source = pair_files
    src_m = write_points(tmp_path / "scan_m.csv", source / 1000.0)
    tgt_m = write_points(tmp_path / "design_m.csv", read_points(tgt_path).points / 1000.0)
    assert main(["register", str(src_m), str(tgt_m), "--units", "m", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert 0.3 < data["rms_mm"] < 1.1  # reported in mm


def test_register_paired_needs_equal_counts(pair_files, capsys, tmp_path):
    src_path, tgt_path, _, source = pair_files
    short = write_points(tmp_path / "short.csv", source[:-10])
    code = main(["register", str(short), str(tgt_path), "--method", "paired"])
    assert code == 2
    err = capsys.readouterr().err
    assert "same number of points" in err and "Traceback" not in err


def test_register_missing_file(pair_files, capsys, tmp_path):
    src_path, _, _, _ = pair_files
    code = main(["register", str(src_path), str(tmp_path / "nothere.csv")])
    assert code == 2
    assert "not found" in capsys.readouterr().err


def test_register_bad_option(pair_files, capsys):
    src_path, tgt_path, _, _ = pair_files
    assert main(["register", str(src_path), str(tgt_path), "--method", "magic"]) == 2
