"""``mppf register``: the JSON transform, -o MOVED, --units m, and what it says when the
in-plane position cannot be fixed."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mppf.cli import main
from mppf.geometry.read import read_points
from mppf.geometry.write import write_points
from mppf.core.transform import apply_tf, make_tf

TF_TRUE = make_tf(Rotation.from_euler("xyz", [25, -15, 40], degrees=True).as_matrix(), [1200.0, -700.0, 350.0])


@pytest.fixture()
def moved_copy(tmp_path, hull_dir):
    """P1 (hull coordinates) and a moved copy with 0.5 mm noise, in mm and in metres."""
    source = read_points(hull_dir / "P1_midbody_bilge.csv").points
    target = apply_tf(TF_TRUE, source) + np.random.default_rng(8).normal(scale=0.5, size=source.shape)
    paths = {
        "mm": (write_points(tmp_path / "src.csv", source), write_points(tmp_path / "tgt.txt", target)),
        "m": (write_points(tmp_path / "src_m.csv", source / 1000), write_points(tmp_path / "tgt_m.xyz", target / 1000)),
    }
    return source, paths


def _run_json(capsys, *args) -> dict:
    assert main(["register", *map(str, args), "--json"]) == 0
    return json.loads(capsys.readouterr().out)


@pytest.mark.parametrize("method", ["point", "plane", "paired"])
def test_json_transform_is_the_4x4_row_major_motion(moved_copy, capsys, tmp_path, method):
    source, paths = moved_copy
    out = tmp_path / "moved.ply"
    data = _run_json(capsys, *paths["mm"], "--method", method, "-o", out)
    assert data["method"] == method and isinstance(data["iterations"], int)
    tf = np.array(data["transform"])
    assert tf.shape == (4, 4) and tf[3].tolist() == [0.0, 0.0, 0.0, 1.0]
    # row-major: rows are (R | t); every point of the plate lands within 1 mm of its true place
    assert np.abs(apply_tf(tf, source) - apply_tf(TF_TRUE, source)).max() < 1.0
    moved = read_points(out).points  # -o: the source moved by exactly that transform
    np.testing.assert_allclose(moved, apply_tf(tf, source), atol=1e-6)
    assert data["output"] == str(out)
    assert 0.3 < data["rms_mm"] < 1.1


def test_units_m_gives_the_transform_and_moved_file_in_mm(moved_copy, capsys, tmp_path):
    source, paths = moved_copy
    in_mm = _run_json(capsys, *paths["mm"])
    out = tmp_path / "moved.csv"
    in_m = _run_json(capsys, *paths["m"], "--units", "m", "-o", out)
    np.testing.assert_allclose(in_m["transform"], in_mm["transform"], atol=1e-6)
    assert in_m["rms_mm"] == pytest.approx(in_mm["rms_mm"], rel=1e-6)
    moved = read_points(out).points
    assert np.abs(moved - apply_tf(TF_TRUE, source)).max() < 1.0  # mm, not metres


def test_units_m_on_fit_matches_mm(moved_copy, capsys):
    _, paths = moved_copy
    assert main(["fit", str(paths["mm"][0]), "--json"]) == 0
    in_mm = json.loads(capsys.readouterr().out)
    assert main(["fit", str(paths["m"][0]), "--units", "m", "--json"]) == 0
    in_m = json.loads(capsys.readouterr().out)
    assert in_m["rms_mm"] == pytest.approx(in_mm["rms_mm"], rel=1e-6)
    np.testing.assert_allclose(in_m["frame"]["origin"], in_mm["frame"]["origin"], rtol=1e-9)


def test_unwritable_output_is_refused_before_registering(moved_copy, capsys, tmp_path):
    _, paths = moved_copy
    assert main(["register", *map(str, paths["mm"]), "-o", str(tmp_path / "moved.stl")]) == 2
    captured = capsys.readouterr()
    assert "moved.stl" in captured.err and ".ply" in captured.err and captured.out == ""
    assert main(["register", *map(str, paths["mm"]), "-o", str(tmp_path / "no" / "moved.csv")]) == 2
    assert "cannot write" in capsys.readouterr().err
    assert not any(tmp_path.glob("moved*")) and not (tmp_path / "no").exists()


def test_partial_scan_of_a_saddle_says_the_in_plane_shift_is_not_fixed(tmp_path, capsys):
    # a saddle (radius 8 m) and a scan of two thirds of it: the outline cannot pin the
    # in-plane position and the shallow surface does not fix it either
    rng = np.random.default_rng(5)
    u, v = np.meshgrid(np.arange(-1500, 1501, 30.0), np.arange(-750, 751, 30.0))
    design = np.column_stack([u.ravel(), v.ravel(), (u.ravel() ** 2 - v.ravel() ** 2) / 16000])
    su, sv = rng.uniform(-1500, 500, 8000), rng.uniform(-750, 750, 8000)
    scan = np.column_stack([su, sv, (su * su - sv * sv) / 16000]) + rng.normal(scale=0.5, size=(8000, 3))
    src = write_points(tmp_path / "scan.csv", scan + [20, -10, 5])
    tgt = write_points(tmp_path / "design.csv", design)
    data = _run_json(capsys, src, tgt, "--method", "plane", "--init", "identity")
    assert data["outline_pinned"] is False
    assert data["uncertainty"]["t_u_mm"] is None
    assert any("in-plane shift along u" in note and "not fixed" in note for note in data["notes"])
    assert main(["register", str(src), str(tgt), "--method", "plane", "--init", "identity"]) == 0
    captured = capsys.readouterr()
    assert "t_u free" in captured.out
    assert "not fixed by the surface shape" in " ".join(captured.err.split())


@pytest.mark.parametrize("option", [["--trim", "0.1"], ["--init", "identity"], ["--robust", "tukey"],
                                    ["--max-iterations", "5"], ["--pin-outline", "no"]])
def test_icp_options_with_paired_are_refused(moved_copy, capsys, option):
    _, paths = moved_copy
    assert main(["register", *map(str, paths["mm"]), "--method", "paired", *option]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert f"{option[0]} only applies to ICP" in err and "Traceback" not in err


@pytest.mark.parametrize("value", ["-1", "0", "nan", "inf"])
def test_fit_bad_spline_smoothing_exit_2(hull_dir, capsys, value):
    assert main(["fit", str(hull_dir / "P1_midbody_bilge.csv"), "--kind", "spline", "--smoothing", value]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "smoothing must be a positive, finite RMS" in err and "what to do:" in err


def test_file_names_with_brackets_are_printed_as_they_are(tmp_path, hull_dir, capsys):
    # rich would take "[bold]" for markup and print "ax.csv"
    source = read_points(hull_dir / "P3_stern_saddle.csv").points
    src = write_points(tmp_path / "a[bold]x.csv", source)
    tgt = write_points(tmp_path / "b[red]y.csv", apply_tf(TF_TRUE, source))
    out = tmp_path / "m[i]z.csv"
    assert main(["fit", str(src)]) == 0
    assert "a[bold]x.csv" in capsys.readouterr().out.replace("\n", "")
    assert main(["register", str(src), str(tgt), "-o", str(out)]) == 0
    text = "".join(capsys.readouterr().out.split())
    assert "a[bold]x.csv->" in text and "b[red]y.csv" in text and "m[i]z.csv" in text
