"""Tests of ``mppf unfold``: the flat file, the report, the picture, the errors."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mppf.cli import main
from mppf.geometry.read import read_points
from mppf.geometry.unfold import unfold

HULL = Path(__file__).resolve().parents[2] / "mppf" / "examples" / "hull"
DESIGN = HULL / "P1_midbody_bilge_smooth.csv"


def _write(path: Path, points) -> Path:
    np.savetxt(path, np.asarray(points, dtype=float), delimiter=",", header="x,y,z")
    return path


def test_unfold_writes_flat_file_in_design_order(tmp_path, capsys):
    out = tmp_path / "flat.csv"
    assert main(["unfold", str(DESIGN), "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "strain RMS" in printed and "outline length change" in printed and "flat file" in printed
    design = read_points(DESIGN).points
    flat = read_points(out).points
    assert flat.shape == design.shape
    assert np.all(flat[:, 2] == 0.0)
    np.testing.assert_allclose(flat, unfold(design).flat, atol=1e-9)


def test_unfold_json_report(tmp_path, capsys):
    out = tmp_path / "flat.ply"
    assert main(["unfold", str(HULL / "K3_stern_saddle.csv"), "-o", str(out), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    for key in ("rms_strain_pct", "max_strain_pct", "area_change_pct", "outline_length_change_pct",
                "n_points", "warnings", "output"):
        assert key in report
    expected = unfold(read_points(HULL / "K3_stern_saddle.csv").points)
    assert report["n_points"] == 2501 and report["output"] == str(out)
    assert report["rms_strain_pct"] == pytest.approx(expected.rms_strain_pct, rel=1e-9)
    assert report["max_strain_pct"] == pytest.approx(expected.max_strain_pct, rel=1e-9)
    assert report["area_change_pct"] == pytest.approx(expected.area_change_pct, abs=1e-9)
    assert report["warnings"] == []
    written = read_points(out)
    assert written.points.shape == (2501, 3) and written.faces.shape == expected.faces.shape


def test_unfold_strain_limit_warns(tmp_path, capsys):
    out = tmp_path / "flat.csv"
    assert main(["unfold", str(HULL / "P2_bow_flare.csv"), "-o", str(out), "--strain-limit", "0.01"]) == 0
    printed = " ".join(capsys.readouterr().out.split())
    assert "warning:" in printed and "exceeds the limit 0.01 %" in printed
    assert main(["unfold", str(HULL / "P2_bow_flare.csv"), "-o", str(out), "--strain-limit", "0.01",
                 "--json"]) == 0
    warnings = json.loads(capsys.readouterr().out)["warnings"]
    assert len(warnings) == 1 and "near the" in warnings[0]


def test_unfold_plot_writes_png(tmp_path, capsys):
    out, picture = tmp_path / "flat.csv", tmp_path / "strain.png"
    assert main(["unfold", str(DESIGN), "-o", str(out), "--plot", str(picture)]) == 0
    assert picture.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert picture.stat().st_size > 20_000


def test_unfold_units_m(tmp_path, capsys):
    design_m = _write(tmp_path / "design_m.csv", read_points(DESIGN).points / 1000.0)
    out = tmp_path / "flat.csv"
    assert main(["unfold", str(design_m), "-o", str(out), "--units", "m", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    width, height = report["flat_size_mm"]
    assert 3000.0 <= width < 3010.0 and 2000.0 <= height < 2030.0


@pytest.mark.parametrize(
    ("points", "message"),
    [
        ([[0, 0, 0], [1000, 0, 0]], "2 point"),
        ([[0, 0, 0], [500, 500, 0], [1000, 1000, 0], [1500, 1500, 0]], "collinear"),
    ],
)
def test_unfold_bad_geometry_exits_2(tmp_path, capsys, points, message):
    design = _write(tmp_path / "bad.csv", points)
    assert main(["unfold", str(design), "-o", str(tmp_path / "flat.csv")]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "error:" in err and message in err and "Traceback" not in err
    assert not (tmp_path / "flat.csv").exists()


def test_unfold_folded_plate_exits_2(tmp_path, capsys):
    t, y = np.meshgrid(np.linspace(0, 1.5 * np.pi, 60), np.linspace(0, 2000, 20), indexing="ij")
    folded = np.column_stack([(800 * np.sin(t) + 200 * t).ravel(), y.ravel(), (-800 * np.cos(t)).ravel()])
    design = _write(tmp_path / "folded.csv", folded)
    assert main(["unfold", str(design), "-o", str(tmp_path / "flat.csv")]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "the plate folds over" in err and "what to do:" in err


@pytest.mark.parametrize(
    ("output", "message"),
    [("missing/flat.csv", "does not exist"), ("flat.docx", "unknown point file type")],
)
def test_unfold_unwritable_output_exits_2(tmp_path, capsys, output, message):
    assert main(["unfold", str(DESIGN), "-o", str(tmp_path / output)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert message in err and "what to do:" in err


def test_unfold_unwritable_plot_exits_2(tmp_path, capsys):
    picture = tmp_path / "missing" / "strain.png"
    assert main(["unfold", str(DESIGN), "-o", str(tmp_path / "flat.csv"), "--plot", str(picture)]) == 2
    assert "cannot write the strain picture" in " ".join(capsys.readouterr().err.split())
    assert not (tmp_path / "flat.csv").exists()  # refused before any work


def test_console_script_bad_input_exit_code(tmp_path):
    design = _write(tmp_path / "two.csv", [[0, 0, 0], [1, 2, 3]])
    proc = subprocess.run([sys.executable, "-m", "mppf", "unfold", str(design), "-o", str(tmp_path / "f.csv")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert "2 point" in proc.stderr and "Traceback" not in proc.stderr


def test_unfold_reads_a_step_design(tmp_path, capsys):
    from cad_helpers import trimmed_plate_area_mm2, write_bspline_plate

    design = write_bspline_plate(tmp_path / "plate.step")
    out = tmp_path / "flat.csv"
    assert main(["unfold", str(design), "-o", str(out), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    cloud = read_points(design)
    assert report["n_points"] == cloud.n_points and report["design_sha256"] == cloud.sha256
    assert report["max_strain_pct"] < 0.1  # a 55 mm deep, 3 x 2 m plate: nearly developable
    flat = read_points(out).points
    # the flat keeps the trimmed plate's area (the cut corner included)
    tri = cloud.faces
    a, b, c = flat[tri[:, 0]], flat[tri[:, 1]], flat[tri[:, 2]]
    flat_area = 0.5 * np.abs(np.cross(b - a, c - a)[:, 2]).sum()
    assert flat_area == pytest.approx(trimmed_plate_area_mm2(), rel=1e-3)


def test_unfold_scale_reads_a_model_scale_design(tmp_path, capsys):
    model = _write(tmp_path / "model.csv", read_points(DESIGN).points / 31.6)
    out = tmp_path / "flat.csv"
    assert main(["unfold", str(model), "-o", str(out), "--scale", "31.6", "--json"]) == 0
    width, height = json.loads(capsys.readouterr().out)["flat_size_mm"]
    assert 3000.0 <= width < 3010.0 and 2000.0 <= height < 2030.0
    assert main(["unfold", str(model), "-o", str(out), "--scale", "0"]) == 2
    assert "--scale" in capsys.readouterr().err


@pytest.mark.parametrize("suffix, message", [(".e57", "does not start with 'ASTM-E57'"),
                                             (".las", "does not start with 'LASF'"),
                                             (".laz", "does not start with 'LASF'")])
def test_unfold_bad_scan_files_exit_2(tmp_path, capsys, suffix, message):
    from cad_helpers import truncated, write_e57, write_las

    points = np.random.default_rng(2).uniform(0.0, 3.0, size=(2000, 3))
    good = write_e57(tmp_path / "good.e57", [(points, (1, 0, 0, 0), (0, 0, 0))]) if suffix == ".e57" \
        else write_las(tmp_path / f"good{suffix}", points)
    empty, text = tmp_path / f"empty{suffix}", tmp_path / f"text{suffix}"
    empty.write_bytes(b"")
    text.write_text("1,2,3\n4,5,6\n")
    for path, expected in ((empty, "file is empty"), (text, message),
                           (truncated(good, tmp_path / f"cut{suffix}"), "truncated|not a readable")):
        assert main(["unfold", str(path), "-o", str(tmp_path / "flat.csv"), "--units", "m"]) == 2
        err = " ".join(capsys.readouterr().err.split())
        assert f"error: {path}" in err and "what to do:" in err and "Traceback" not in err
        assert any(part in err for part in expected.split("|"))
    assert not (tmp_path / "flat.csv").exists()
