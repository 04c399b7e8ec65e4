"""Laser-scanner files in (mppf.geometry.scans): E57 with several posed scans, LAS and LAZ.

The files are written by the libraries themselves (pye57, laspy with lazrs) and read back
through :func:`mppf.geometry.read.read_points`, as every command reads a scan or a design.
"""

from __future__ import annotations

import numpy as np
import pytest

from cad_helpers import truncated, write_e57, write_las
from mppf.core.errors import FileFormatError
from mppf.core.transform import quaternion_to_matrix
from mppf.geometry import files
from mppf.geometry.read import read_points

RNG = np.random.default_rng(11)
LOCAL_M = RNG.uniform(-1.5, 1.5, size=(500, 3))
"""Points of a scan in its scanner's own frame, metres."""

POSES = [
    ((1.0, 0.0, 0.0, 0.0), (2.0, -1.0, 0.5)),  # no rotation, a shift
    (tuple(np.r_[np.cos(0.3), np.sin(0.3) * np.array([0.2, -0.3, 0.932]) / np.linalg.norm([0.2, -0.3, 0.932])]),
     (10.0, 4.0, -2.0)),  # 34 degrees about a tilted axis
]


@pytest.fixture(scope="module")
def two_scans(tmp_path_factory):
    path = tmp_path_factory.mktemp("e57") / "two.e57"
    return write_e57(path, [(LOCAL_M, q, t) for q, t in POSES])


def test_e57_reads_every_scan_with_its_pose(two_scans):
    cloud = read_points(two_scans, units="mm")  # E57 is metres by the standard, whatever --units says
    expected = np.vstack([(LOCAL_M @ quaternion_to_matrix(q).T + t) * 1000.0 for q, t in POSES])
    assert cloud.points.shape == (1000, 3) and cloud.faces is None
    np.testing.assert_allclose(cloud.points, expected, atol=1e-3)  # pye57 stores single precision: 0.1 um
    assert len(cloud.sha256) == 64


def test_e57_scale_applies(two_scans):
    np.testing.assert_allclose(read_points(two_scans, scale=2.0).points, 2.0 * read_points(two_scans).points)


def test_e57_leaves_nothing_on_the_terminal(two_scans, tmp_path, capfd):
    read_points(two_scans)
    with pytest.raises(FileFormatError):
        read_points(truncated(two_scans, tmp_path / "cut.e57"))
    out, err = capfd.readouterr()
    assert out == "" and err == ""  # libE57Format prints its exceptions to stderr itself


@pytest.mark.parametrize("suffix", [".las", ".laz"])
def test_las_and_laz_scale_and_offset(tmp_path, suffix):
    points_m = RNG.uniform(-2.0, 2.0, size=(2000, 3)) + [512345.0, 6712345.0, 12.0]  # UTM-like metres
    path = write_las(tmp_path / f"scan{suffix}", points_m, scale=(0.0005, 0.0005, 0.0002),
                     offset=(512000.0, 6712000.0, 0.0))
    cloud = read_points(path, units="m")
    assert cloud.points.shape == (2000, 3)
    np.testing.assert_allclose(cloud.points, points_m * 1000.0, atol=0.26)  # half a quantum: 0.25 mm
    raw = read_points(path, units="mm")  # LAS has no unit of its own: --units says which
    np.testing.assert_allclose(raw.points * 1000.0, cloud.points, rtol=1e-12)


def test_laz_is_compressed(tmp_path):
    points = RNG.uniform(0.0, 3.0, size=(5000, 3))
    las, laz = (write_las(tmp_path / f"s.{s}", points) for s in ("las", "laz"))
    assert laz.stat().st_size < 0.5 * las.stat().st_size
    np.testing.assert_array_equal(read_points(las, units="m").points, read_points(laz, units="m").points)


@pytest.mark.parametrize("suffix", [".e57", ".las", ".laz"])
def test_bad_scan_files(tmp_path, suffix):
    points = RNG.uniform(0.0, 3.0, size=(3000, 3))
    good = write_e57(tmp_path / "good.e57", [(points, (1, 0, 0, 0), (0, 0, 0))]) if suffix == ".e57" \
        else write_las(tmp_path / f"good{suffix}", points)
    empty = tmp_path / f"empty{suffix}"
    empty.write_bytes(b"")
    text = tmp_path / f"points{suffix}"
    text.write_text("x,y,z\n1,2,3\n")
    cut = truncated(good, tmp_path / f"cut{suffix}", 0.5)
    magic = "ASTM-E57" if suffix == ".e57" else "LASF"
    for path, message in ((empty, "file is empty"), (text, f"does not start with '{magic}'"),
                          (cut, "truncated|not a readable"), (tmp_path / f"none{suffix}", "file not found")):
        with pytest.raises(FileFormatError, match=message) as info:
            read_points(path, units="m")
        assert str(path) in str(info.value) and info.value.hint


@pytest.mark.parametrize("suffix", [".e57", ".las", ".csv"])
def test_files_larger_than_memory_are_refused(tmp_path, monkeypatch, suffix):
    points = RNG.uniform(0.0, 3.0, size=(3000, 3))
    if suffix == ".e57":
        path = write_e57(tmp_path / "big.e57", [(points, (1, 0, 0, 0), (0, 0, 0))])
    elif suffix == ".las":
        path = write_las(tmp_path / "big.las", points)
    else:
        path = tmp_path / "big.csv"
        np.savetxt(path, points, delimiter=",")
    monkeypatch.setattr(files, "available_bytes", lambda: 50_000)
    with pytest.raises(FileFormatError, match="too large to read") as info:
        read_points(path, units="m")
    assert "GiB" in str(info.value) and info.value.hint
