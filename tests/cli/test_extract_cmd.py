"""``mppf extract``: a plate cut from the KCS hull IGES at model scale; bad files and regions exit 2."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from cad_helpers import KCS_IGES, KCS_SCALE, truncated, write_box_hull, write_bspline_plate, write_e57
from mppf.cli import main
from mppf.geometry.read import read_points

K1_X = ("113498.9", "116499.7")
K1_GIRTH = ("14251.5", "16253.3")


@pytest.fixture(scope="module")
def box_hull(tmp_path_factory):
    """A small box-bilge hull (STEP, by gmsh): quick to read."""
    return write_box_hull(tmp_path_factory.mktemp("hull") / "box.step")


def test_extract_k1_by_butts_and_seams_as_csv(tmp_path, capfd):
    out = tmp_path / "k1.csv"
    code = main(["extract", str(KCS_IGES), "--scale", str(KCS_SCALE), "--x", *K1_X, "--girth", *K1_GIRTH,
                 "--spacing", "100", "-o", str(out), "--json"])
    printed, err = capfd.readouterr()
    assert code == 0 and err == ""
    report = json.loads(printed)  # nothing but the report on stdout: gmsh and OpenCASCADE stay quiet
    assert report["n_surfaces"] == 18 and report["grid_shape"] == [32, 22] and report["n_points"] == 704
    np.testing.assert_allclose(report["size_mm"], [3000.8, 2001.8], atol=0.5)
    assert report["chord_mm"] < 0.5 and report["read_s"] > 0  # 100 mm cells on a 3.3 m bilge: about 0.4 mm
    plate = read_points(out)
    assert plate.points.shape == (704, 3)
    assert "grid 32 x 22, row by row" in out.read_text().splitlines()[0]
    rows = plate.points.reshape(32, 22, 3)
    np.testing.assert_allclose(rows[:, 0, 0], np.linspace(113498.9, 116499.7, 32), atol=1e-6)  # a station per row


@pytest.mark.parametrize("suffix", [".stl", ".obj", ".ply"])
def test_extract_writes_a_mesh(box_hull, tmp_path, capsys, suffix):
    out = tmp_path / f"bottom{suffix}"
    polygon = "1000,1000 3000,1000 3000,5000 1000,5000"
    assert main(["extract", str(box_hull), "--polygon", polygon, "--seen-from", "-z", "--spacing", "100",
                 "-o", str(out)]) == 0
    printed = " ".join(capsys.readouterr().out.split())
    assert "3 surfaces" in printed and "21 x 41 at 100 mm, 861 points, 1600 triangles" in printed
    if suffix == ".ply":
        mesh = read_points(out)
        vertices, faces = mesh.points, mesh.faces
    else:
        loaded = trimesh.load(str(out), process=False)
        vertices, faces = loaded.vertices, loaded.faces
    assert len(faces) == 1600 and np.allclose(vertices[:, 2], 0.0)  # the bottom, seen from below
    assert np.ptp(vertices[:, 0]) == pytest.approx(2000.0) and np.ptp(vertices[:, 1]) == pytest.approx(4000.0)


@pytest.mark.parametrize(
    "name, make, message",
    [
        ("empty.igs", lambda p: p.write_bytes(b""), "file is empty"),
        ("cut.igs", lambda p: truncated(KCS_IGES, p, 0.4), "is truncated"),
        ("points.igs", lambda p: p.write_text("x,y,z\n1,2,3\n"), "is not an IGES file"),
        ("cut.stp", lambda p: truncated(write_bspline_plate(p.with_name("plate.stp")), p, 0.5), "is truncated"),
        ("points.step", lambda p: p.write_text("1 2 3\n"), "is not a STEP file"),
        ("missing.igs", lambda p: None, "file not found"),
    ],
)
def test_bad_hull_files_exit_2(tmp_path, capfd, name, make, message):
    path = tmp_path / name
    make(path)
    code = main(["extract", str(path), "--x", "0", "1000", "--girth", "0", "1000", "-o", str(tmp_path / "p.csv")])
    out, err = capfd.readouterr()
    err = " ".join(err.split())
    assert code == 2 and out == ""
    assert f"error: {path}" in err and message in err and "what to do:" in err and "Traceback" not in err
    assert not (tmp_path / "p.csv").exists()


@pytest.mark.parametrize(
    "args, message",
    [
        ([], "either as --polygon or as --x and --girth"),
        (["--x", "0", "1000"], "--x and --girth go together"),
        (["--polygon", "1,2 3,4"], "at least 3 corners"),
        (["--polygon", "1,2 3,4 5,6", "--seen-from", "y"], "signed hull axis"),
        (["--x", "1000", "1000", "--girth", "0", "100"], "must span a length"),
        (["--x", "30000", "31000", "--girth", "0", "100"], "no keel at x = 30000 mm"),
        (["--x", "0", "1000", "--girth", "20000", "21000", "--spacing", "500"], "ends at a girth of 2071"),
        (["--polygon", "1000,13000 2000,13000 2000,14000", "--seen-from", "+y"], "do not meet the hull"),
    ],
)
def test_bad_regions_exit_2(box_hull, tmp_path, capsys, args, message):
    code = main(["extract", str(box_hull), *args, "-o", str(tmp_path / "p.csv")])
    err = " ".join(capsys.readouterr().err.split())
    assert code == 2 and message in err and "what to do:" in err


def test_a_scan_is_not_a_hull_model(tmp_path, capsys):
    scan = write_e57(tmp_path / "scan.e57", [(np.zeros((3, 3)), (1, 0, 0, 0), (0, 0, 0))])
    code = main(["extract", str(scan), "--x", "0", "1", "--girth", "0", "1", "-o", str(tmp_path / "p.csv")])
    err = " ".join(capsys.readouterr().err.split())
    assert code == 2 and "is not a CAD model: its suffix '.e57'" in err and "what to do:" in err
