"""Writing point files, read back exactly (mppf.geometry.write)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from mppf.core.errors import InputError
from mppf.geometry.read import read_points
from mppf.geometry.write import write_points


@pytest.fixture()
def cloud():
    rng = np.random.default_rng(7)
    return rng.uniform(-1500.0, 1500.0, size=(50, 3)) + [176000.0, 12000.0, 3000.0]


@pytest.mark.parametrize("suffix", [".csv", ".txt", ".xyz", ".ply"])
def test_write_read_round_trip_exact(tmp_path, cloud, suffix):
    path = write_points(tmp_path / f"c{suffix}", cloud, header="round trip")
    np.testing.assert_array_equal(read_points(path).points, cloud)


def test_write_ply_with_faces(tmp_path):
    mesh = trimesh.creation.icosphere(subdivisions=1, radius=500.0)
    path = write_points(tmp_path / "m.ply", mesh.vertices, faces=mesh.faces)
    pc = read_points(path)
    np.testing.assert_allclose(pc.points, mesh.vertices)
    np.testing.assert_array_equal(pc.faces, mesh.faces)


def test_write_unknown_suffix(tmp_path, cloud):
    with pytest.raises(InputError, match="unknown point file type"):
        write_points(tmp_path / "c.dat", cloud)


def test_write_into_missing_folder(tmp_path, cloud):
    with pytest.raises(InputError, match="cannot write"):
        write_points(tmp_path / "no" / "such" / "c.csv", cloud)


def test_write_bad_shape(tmp_path):
    with pytest.raises(InputError, match=r"\(n, 3\)"):
        write_points(tmp_path / "c.csv", np.zeros((4, 2)))
