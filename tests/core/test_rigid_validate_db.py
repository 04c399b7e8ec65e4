"""The one rigid fit, the one numeric validator, the one way of opening SQLite."""

import sqlite3

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mppf.core.db import open_sqlite
from mppf.core.errors import ConfigError, InputError
from mppf.core.rigid import fit_rigid
from mppf.core.validate import NumberRange, check_number, check_positive


def test_fit_rigid_recovers_a_motion_in_3d_and_in_the_plane():
    rng = np.random.default_rng(4)
    p = rng.uniform(-1000.0, 1000.0, (50, 3))
    rot = Rotation.from_euler("zyx", [40.0, -10.0, 5.0], degrees=True).as_matrix()
    shift = np.array([1.0e5, -2.0e4, 300.0])
    tf = fit_rigid(p, p @ rot.T + shift)
    np.testing.assert_allclose(tf[:3, :3], rot, atol=1e-10)
    np.testing.assert_allclose(tf[:3, 3], shift, atol=1e-6)
    angle = np.radians(-25.0)
    r2 = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    q = p[:, :2]
    tf2 = fit_rigid(q, q @ r2.T + [5.0, -7.0], weights=np.linspace(1.0, 2.0, len(q)))
    assert tf2.shape == (3, 3)
    np.testing.assert_allclose(tf2[:2, :2], r2, atol=1e-10)
    np.testing.assert_allclose(tf2[:2, 2], [5.0, -7.0], atol=1e-8)


@pytest.mark.parametrize("value, kwargs, message", [
    (True, {}, "must be a number, got True"),
    ("20", {}, "must be a number, got '20'"),
    (float("inf"), {}, "must be a finite number"),
    (0.0, {"low": 0.0, "low_open": True, "unit": "mm"}, "must be above 0 mm, got 0.0 mm"),
    (2.5, {"integer": True}, "must be a whole number"),
    (60, {"integer": True, "low": 1, "high": 50}, "must be from 1 to 50, got 60"),
])
def test_check_number_refuses_with_the_name_the_value_and_the_range(value, kwargs, message):
    with pytest.raises(InputError, match=message) as info:
        check_number("--thing", value, **kwargs)
    assert "--thing" in info.value.message and info.value.hint


def test_check_number_accepts_and_converts():
    assert check_number("n", 3.0, integer=True) == 3 and isinstance(check_number("n", 3.0, integer=True), int)
    assert check_positive("t", np.float64(20.0), unit="mm") == 20.0
    with pytest.raises(ConfigError):
        check_positive("[press] rows", -1, error=ConfigError)


def test_number_range_says_its_range_and_holds_its_numbers():
    assert NumberRange(low=0.0, high=5.0, unit="mm").text() == "from 0 to 5 mm"
    assert NumberRange(low=0.0, low_open=True).text() == "above 0"
    assert NumberRange().text() == "finite"
    assert NumberRange(low=0.0, high=5.0, high_open=True).holds(0.0)
    assert not NumberRange(low=0.0, high=5.0, high_open=True).holds(5.0)
    with pytest.raises(TypeError, match="lo"):
        check_number("n", 1.0, lo=0.0)  # a misspelt limit is a bug in the caller, not a value to ignore


def test_open_sqlite_creates_applies_the_schema_and_refuses_another_version(tmp_path):
    path = tmp_path / "sub" / "x.sqlite"
    db = open_sqlite(path, "the test file", "CREATE TABLE IF NOT EXISTS t (a)", 3, hint="h")
    db.execute("INSERT INTO t VALUES (1)")
    assert db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    db.close()
    with pytest.raises(InputError, match="schema version 3, this mppf reads 4"):
        open_sqlite(path, "the test file", "CREATE TABLE IF NOT EXISTS t (a)", 4, hint="h")
    (tmp_path / "bad.sqlite").write_text("not a database at all " * 100)
    with pytest.raises(InputError, match="cannot open the test file"):
        open_sqlite(tmp_path / "bad.sqlite", "the test file", "CREATE TABLE IF NOT EXISTS t (a)", 1, hint="h")
    assert isinstance(sqlite3.connect(path).execute("SELECT a FROM t").fetchone()[0], int)
