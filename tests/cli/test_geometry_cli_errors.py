"""Every bad-input case of "Reading plates" through the command line: exit 2, one message
naming the file (and the line where it applies), no traceback, for ``fit`` and ``register``."""

from __future__ import annotations

import numpy as np
import pytest

from mppf.cli import main


def _folded_plate() -> np.ndarray:
    """A cylinder arc curled past a half circle: folds over its best-fit plane."""
    theta, y = np.meshgrid(np.radians(np.linspace(0, 300, 60)), np.linspace(0, 3000, 12))
    return np.column_stack([400 * np.sin(theta.ravel()), y.ravel(), 400 * (1 - np.cos(theta.ravel()))])


def _lines(points: np.ndarray) -> str:
    return "".join(f"{x!r},{y!r},{z!r}\n" for x, y, z in points.tolist())


# name, content (str for text, bytes for binary), words expected in the message, line (or None)
BAD_FILES = {
    "missing": ("missing.csv", None, "file not found", None),
    "empty": ("empty.csv", "", "empty", None),
    "only header": ("header.csv", "# scan\nx,y,z\n", "no numeric data", None),
    "non-numeric": ("text.csv", "x,y,z\n1,2,3\n4,abc,6\n", "non-numeric field 'abc'", 3),
    "too few columns": ("two.csv", "1,2\n3,4\n5,6\n", "2 column(s)", 1),
    "ragged columns": ("ragged.txt", "1 2 3\n4 5 6\n7 8\n", "expected 3", 3),
    "NaN": ("nan.csv", "1,2,3\n4,nan,6\n7,8,9\n", "NaN", 2),
    "inf": ("inf.xyz", "1 2 3\n4 5 6\n1 1 -inf\n", "infinite", 3),
    "too few points": ("few.csv", "0,0,0\n1,0,0\n0,1,0\n1,1,1\n", "the fit needs at least", None),
    "coincident": ("same.csv", "5,5,5\n" * 30, "coincide", None),
    "collinear": ("line.csv", _lines(np.linspace(0, 3000, 40)[:, None] * [1.0, 0.5, 0.25]), "collinear", None),
    "folds over": ("curl.csv", _lines(_folded_plate()), "folds over", None),
    "binary named csv": ("junk.csv", np.random.default_rng(1).bytes(2000), "binary", None),
    "text named ply": ("points.ply", "1,2,3\n4,5,6\n", "not a PLY file", 1),
    "broken ply header": ("broken.ply", "ply\nformat ascii 1.0\nelement vertex 2\nbogus\n", "PLY", None),
    "text named stl": ("points.stl", "1,2,3\n4,5,6\n", "STL", None),
    "text named obj": ("points.obj", "1,2,3\n4,5,6\n", "OBJ", None),
    "unknown suffix": ("points.dat", "1 2 3\n", "unknown file type", None),
}


@pytest.fixture()
def bad_file(request, tmp_path):
    name, content, words, line = BAD_FILES[request.param]
    path = tmp_path / name
    if isinstance(content, bytes):
        path.write_bytes(content)
    elif content is not None:
        path.write_text(content)
    return path, words, line


def _check_message(err: str, path, words: str, line) -> None:
    text = " ".join(err.split())  # undo the console's line wrapping
    assert "Traceback" not in err and "internal error" not in err
    assert text.startswith("error:") and path.name in text
    assert words in text
    if line is not None:
        assert f"{path.name}, line {line}:" in text
    assert "what to do:" in text


@pytest.mark.parametrize("bad_file", list(BAD_FILES), indirect=True)
def test_fit_bad_file_exit_2(bad_file, capsys):
    path, words, line = bad_file
    assert main(["fit", str(path)]) == 2
    _check_message(capsys.readouterr().err, path, words, line)


@pytest.mark.parametrize("bad_file", [k for k in BAD_FILES if k not in ("folds over", "too few points")],
                         indirect=True)
@pytest.mark.parametrize("side", ["source", "target"])
def test_register_bad_file_exit_2(bad_file, side, hull_dir, capsys):
    path, words, line = bad_file
    good = str(hull_dir / "P3_stern_saddle.csv")
    args = [str(path), good] if side == "source" else [good, str(path)]
    assert main(["register", *args, "--json"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""  # no half-written JSON
    _check_message(captured.err, path, words, line)


def test_register_too_few_points_exit_2(tmp_path, hull_dir, capsys):
    path = tmp_path / "few.csv"
    path.write_text("0,0,0\n1,0,0\n")
    assert main(["register", str(path), str(hull_dir / "P3_stern_saddle.csv")]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "2 point" in err and "Traceback" not in err


def test_fit_too_few_points_for_the_degree_names_the_need(tmp_path, capsys):
    # 20 points: enough for degree 3 (16 coefficients), not for degree 4 (25)
    rng = np.random.default_rng(3)
    u, v = rng.uniform(-1000, 1000, (2, 20))
    path = tmp_path / "p.csv"
    path.write_text(_lines(np.column_stack([u, v, u * v / 5000])))
    assert main(["fit", str(path), "--degree", "3", "--json"]) == 0
    capsys.readouterr()
    assert main(["fit", str(path), "--degree", "4"]) == 2
    assert "20 point(s), the fit needs at least 25" in " ".join(capsys.readouterr().err.split())


def test_directory_instead_of_file_exit_2(tmp_path, capsys):
    folder = tmp_path / "scan.csv"
    folder.mkdir()
    assert main(["fit", str(folder)]) == 2
    assert main(["register", str(folder), str(folder)]) == 2
    assert "Traceback" not in capsys.readouterr().err


def test_unknown_units_is_a_usage_error(hull_dir, capsys):
    assert main(["fit", str(hull_dir / "P1_midbody_bilge.csv"), "--units", "inch"]) == 2
    assert "--units" in capsys.readouterr().err


def test_mesh_with_a_nan_vertex_is_named_not_dropped(tmp_path, capsys):
    path = tmp_path / "nan.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n")
    assert main(["fit", str(path)]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "nan.obj: vertex 2 has a NaN or infinite coordinate" in err


def test_absurd_coordinates_exit_2_not_a_bug(tmp_path, hull_dir, capsys):
    # e.g. a file in mm read with --units m twice over; 1e300 overflowed the frame fit
    points = np.loadtxt(hull_dir / "P1_midbody_bilge.csv", delimiter=",") * 1e300
    path = tmp_path / "huge.csv"
    path.write_text(_lines(points))
    assert main(["fit", str(path)]) == 2
    assert main(["register", str(path), str(hull_dir / "P1_midbody_bilge.csv")]) == 2
    err = " ".join(capsys.readouterr().err.split())
    assert "huge.csv" in err and "beyond 1e+09 mm" in err and "Traceback" not in err
