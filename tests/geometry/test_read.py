"""Reading point and mesh files (mppf.geometry.read)."""

from __future__ import annotations

import hashlib

import numpy as np
import plyfile
import pytest
import trimesh

from mppf.core.errors import FileFormatError, InputError
from mppf.geometry.read import PointCloud, read_points
from mppf.geometry.write import write_points


@pytest.fixture()
def cloud():
    rng = np.random.default_rng(7)
    return rng.uniform(-1500.0, 1500.0, size=(50, 3)) + [176000.0, 12000.0, 3000.0]


def write(tmp_path, name, text, mode="w"):
    path = tmp_path / name
    if mode == "w":
        path.write_text(text)
    else:
        path.write_bytes(text)
    return path


def test_csv_with_header_and_comments(tmp_path):
    path = write(tmp_path, "p.csv", "# scanner export\nx,y,z\n1,2,3\n\n# mid comment\n4, 5 ,6 # trailing\n")
    pc = read_points(path)
    assert isinstance(pc, PointCloud)
    np.testing.assert_array_equal(pc.points, [[1, 2, 3], [4, 5, 6]])
    assert pc.faces is None
    assert pc.path == path
    assert pc.sha256 == hashlib.sha256(path.read_bytes()).hexdigest()
    assert pc.n_points == 2


def test_whitespace_xyz_and_extra_columns(tmp_path):
    path = write(tmp_path, "p.xyz", "X Y Z I\n1.5 2 3 99\n4\t5 6e1 98\n")
    np.testing.assert_array_equal(read_points(path).points, [[1.5, 2, 3], [4, 5, 60]])


def test_units_metres_scale_to_mm(tmp_path):
    path = write(tmp_path, "p.txt", "0.001 0.002 1.5\n1 2 3\n")
    np.testing.assert_allclose(read_points(path, units="m").points, [[1, 2, 1500], [1000, 2000, 3000]])


def test_unknown_unit_is_input_error(tmp_path):
    path = write(tmp_path, "p.txt", "1 2 3\n")
    with pytest.raises(InputError, match="unit"):
        read_points(path, units="inch")


def test_bundled_hull_plates_read(hull_dir):
    files = sorted(hull_dir.glob("*.csv"))
    assert len(files) >= 6
    for path in files:
        pc = read_points(path)
        assert pc.points.shape == (61 * 41, 3)
        assert np.abs(pc.points).max() > 1000.0  # hull coordinates in mm


def test_slow_and_fast_parsers_agree(tmp_path, cloud):
    # mixed separators force the line-by-line parser; the regular file uses numpy's
    regular = write_points(tmp_path / "a.csv", cloud)
    lines = regular.read_text().splitlines()
    mixed_lines = [line.replace(",", " ") if i % 2 else line for i, line in enumerate(lines)]
    mixed = write(tmp_path, "b.txt", "\n".join(mixed_lines) + "\n")
    np.testing.assert_array_equal(read_points(regular).points, read_points(mixed).points)


def test_missing_file(tmp_path):
    with pytest.raises(FileFormatError, match="not found") as info:
        read_points(tmp_path / "nope.csv")
    assert "nope.csv" in str(info.value)


def test_empty_file(tmp_path):
    with pytest.raises(FileFormatError, match="empty"):
        read_points(write(tmp_path, "e.csv", ""))


def test_blank_file_is_empty(tmp_path):
    with pytest.raises(FileFormatError, match="empty"):
        read_points(write(tmp_path, "e.csv", "\n  \n"))


def test_only_comments_and_header(tmp_path):
    with pytest.raises(FileFormatError, match="no numeric data"):
        read_points(write(tmp_path, "h.csv", "# c\nx,y,z\n"))


def test_directory_is_not_a_file(tmp_path):
    folder = tmp_path / "d.csv"
    folder.mkdir()
    with pytest.raises(FileFormatError, match="not a file"):
        read_points(folder)


def test_non_numeric_field_names_line_and_column(tmp_path):
    path = write(tmp_path, "p.csv", "x,y,z\n1,2,3\n4,abc,6\n")
    with pytest.raises(FileFormatError, match="non-numeric field 'abc' in column 2") as info:
        read_points(path)
    assert info.value.line == 3
    assert "line 3" in str(info.value) and "p.csv" in str(info.value)


def test_two_columns_is_wrong_column_count(tmp_path):
    with pytest.raises(FileFormatError, match="2 column") as info:
        read_points(write(tmp_path, "p.csv", "# c\n1,2\n3,4\n"))
    assert info.value.line == 2


def test_inconsistent_column_count(tmp_path):
    with pytest.raises(FileFormatError, match="expected 3") as info:
        read_points(write(tmp_path, "p.txt", "1 2 3\n4 5 6\n7 8 9 10\n"))
    assert info.value.line == 3


def test_nan_field(tmp_path):
    with pytest.raises(FileFormatError, match="NaN") as info:
        read_points(write(tmp_path, "p.csv", "1,2,3\n4,nan,6\n"))
    assert info.value.line == 2


def test_inf_field(tmp_path):
    with pytest.raises(FileFormatError, match="infinite") as info:
        read_points(write(tmp_path, "p.xyz", "1 2 3\n4 5 6\n1 1 -inf\n"))
    assert info.value.line == 3


def test_binary_junk_named_csv(tmp_path):
    junk = np.random.default_rng(1).bytes(2000)
    with pytest.raises(FileFormatError, match="binary"):
        read_points(write(tmp_path, "junk.csv", junk, mode="wb"))


def test_csv_named_ply(tmp_path):
    with pytest.raises(FileFormatError, match="not a PLY"):
        read_points(write(tmp_path, "p.ply", "1,2,3\n4,5,6\n"))


def test_csv_named_stl(tmp_path):
    with pytest.raises(FileFormatError, match="STL"):
        read_points(write(tmp_path, "p.stl", "1,2,3\n4,5,6\n"))


def test_junk_named_obj(tmp_path):
    with pytest.raises(FileFormatError, match="OBJ"):
        read_points(write(tmp_path, "p.obj", "1,2,3\n4,5,6\n"))


def test_unknown_extension(tmp_path):
    with pytest.raises(FileFormatError, match="unknown file type '.dat'"):
        read_points(write(tmp_path, "p.dat", "1 2 3\n"))


def test_broken_ply_header(tmp_path):
    with pytest.raises(FileFormatError, match="PLY"):
        read_points(write(tmp_path, "p.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nbogus\n"))


def test_ply_nan_vertex(tmp_path):
    vertex = np.array([(1.0, 2.0, 3.0), (np.nan, 1.0, 1.0)], dtype=[("x", "f8"), ("y", "f8"), ("z", "f8")])
    path = tmp_path / "n.ply"
    plyfile.PlyData([plyfile.PlyElement.describe(vertex, "vertex")], text=True).write(str(path))
    with pytest.raises(FileFormatError, match="vertex 1"):
        read_points(path)


def test_ply_face_with_missing_vertex(tmp_path):
    path = write(tmp_path, "m.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                 "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
                 "0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n")
    with pytest.raises(FileFormatError, match="vertex 7, but there are 3"):
        read_points(path)


@pytest.mark.parametrize("text", [True, False])
def test_ply_ascii_and_binary_with_quads(tmp_path, text):
    vertex = np.array([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 1)], dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    face = np.empty(1, dtype=[("vertex_indices", "i4", (4,))])
    face["vertex_indices"] = [[0, 1, 2, 3]]
    path = tmp_path / "q.ply"
    plyfile.PlyData(
        [plyfile.PlyElement.describe(vertex, "vertex"), plyfile.PlyElement.describe(face, "face")], text=text
    ).write(str(path))
    pc = read_points(path)
    np.testing.assert_array_equal(pc.points, [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 1]])
    np.testing.assert_array_equal(pc.faces, [[0, 1, 2], [0, 2, 3]])  # quad fanned into 2 triangles


@pytest.mark.parametrize("file_type,name", [("stl", "b.stl"), ("stl_ascii", "a.stl"), ("obj", "m.obj")])
def test_mesh_round_trip_shares_vertices(tmp_path, file_type, name):
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=800.0)
    path = tmp_path / name
    mesh.export(str(path), file_type=file_type)
    pc = read_points(path)
    # STL stores 3 vertices per triangle: the reader merges them back to shared vertices
    assert pc.points.shape == mesh.vertices.shape
    assert pc.faces.shape == mesh.faces.shape
    # same triangles, whatever the vertex order
    np.testing.assert_allclose(
        np.sort(pc.points[pc.faces].reshape(-1, 9), axis=0),
        np.sort(mesh.vertices[mesh.faces].reshape(-1, 9), axis=0),
        atol=1e-3,
    )


def test_obj_with_only_vertices(tmp_path):
    path = write(tmp_path, "p.obj", "v 1 2 3\nv 4 5 6\nv 7 8 10\n")
    pc = read_points(path)
    np.testing.assert_array_equal(pc.points, [[1, 2, 3], [4, 5, 6], [7, 8, 10]])
    assert pc.faces is None
