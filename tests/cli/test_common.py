"""The command line's shared checks: output and database paths refused before any work, plates in the wrong unit, JSON."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from mppf.cli._common import (
    DESIGN_MAX_POINTS,
    PICTURE_SUFFIXES,
    check_db_path,
    check_design_size,
    check_output_path,
    print_json,
    read_input,
)
from mppf.core.errors import GeometryError, InputError
from mppf.geometry.write import write_points


def _plate_points(size_mm: float) -> np.ndarray:
    u, v = np.meshgrid(np.linspace(0.0, size_mm, 12), np.linspace(0.0, size_mm / 2, 8))
    return np.column_stack([u.ravel(), v.ravel(), 1e-4 * (u.ravel() - size_mm / 2) ** 2])


def test_an_output_path_that_can_be_written_is_returned(tmp_path):
    assert check_output_path(str(tmp_path / "flat.png"), "the picture", PICTURE_SUFFIXES) == tmp_path / "flat.png"
    assert check_output_path(tmp_path / "FLAT.PNG", "the picture", PICTURE_SUFFIXES).name == "FLAT.PNG"


@pytest.mark.parametrize(("name", "words"), [
    ("", "the output path is empty"),
    ("flat.jpg", "unknown picture type '.jpg'"),
    ("flat", "unknown picture type '(no suffix)'"),
    ("missing/flat.png", "does not exist"),
])
def test_a_bad_output_path_is_refused_naming_what_and_why(tmp_path, name, words):
    path = "" if not name else tmp_path / name
    with pytest.raises(InputError) as caught:
        check_output_path(path, "the picture", PICTURE_SUFFIXES, kind="picture")
    assert words in str(caught.value) and caught.value.hint


def test_an_output_path_that_is_a_folder_is_refused(tmp_path):
    (tmp_path / "out.csv").mkdir()
    with pytest.raises(InputError, match="it is a folder"):
        check_output_path(tmp_path / "out.csv", "the flat plate")


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write anywhere")
def test_an_output_folder_without_write_permission_is_refused(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    with pytest.raises(InputError, match="permission denied"):
        check_output_path(locked / "job.json", "the job file")


def test_a_database_path_may_lie_in_folders_still_to_be_made(tmp_path):
    path = tmp_path / "a" / "b" / "audit.sqlite"
    assert check_db_path(path, "the audit log", "--audit") == path
    assert not path.parent.exists()  # nothing is created by the check


def test_a_database_path_that_is_a_folder_or_below_a_file_is_refused_naming_the_option(tmp_path):
    with pytest.raises(InputError, match=r"^--history .*: is a folder, not the plate history"):
        check_db_path(tmp_path, "the plate history", "--history")
    (tmp_path / "file").write_text("x")
    with pytest.raises(InputError, match=r"--audit .*is a file, not a folder"):
        check_db_path(tmp_path / "file" / "audit.sqlite", "the audit log", "--audit")


def test_a_design_is_refused_beyond_the_largest_number_of_points():
    check_design_size("plate.csv", DESIGN_MAX_POINTS)
    with pytest.raises(InputError) as caught:
        check_design_size("plate.csv", DESIGN_MAX_POINTS + 1)
    assert f"{DESIGN_MAX_POINTS + 1:,} points" in str(caught.value) and "--spacing" in caught.value.hint


def test_a_plate_in_metres_read_as_millimetres_is_refused_with_the_unit_to_give(tmp_path):
    path = write_points(tmp_path / "plate_m.csv", _plate_points(3.0))  # 3 m written as 3
    with pytest.raises(GeometryError) as caught:
        read_input(path)
    assert "only 3 mm across" in str(caught.value) and "--units m" in caught.value.hint
    cloud = read_input(path, units="m")
    assert np.ptp(cloud.points[:, 0]) == pytest.approx(3000.0)


def test_a_full_size_plate_is_read_in_millimetres(tmp_path):
    cloud = read_input(write_points(tmp_path / "plate.csv", _plate_points(3000.0)))
    assert cloud.n_points == 96 and np.ptp(cloud.points[:, 0]) == pytest.approx(3000.0)


def test_json_output_converts_numpy_values_and_writes_nan_as_null(capsys):
    print_json({"rms_mm": np.float32(0.5), "n": np.int64(3), "ok": np.bool_(True), "grid": np.array([[1.0, np.nan]]),
                "steps": (1, 2), 7: float("inf")})
    assert json.loads(capsys.readouterr().out) == {"rms_mm": 0.5, "n": 3, "ok": True, "grid": [[1.0, None]],
                                                   "steps": [1, 2], "7": None}
